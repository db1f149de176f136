//! Shape complexity K of King & Rossignac (1999), Sec. 4.
//!
//! The surface is modelled as spherical patches, one per interior edge `e = (a, b)` with
//! incident triangles `(a, b, c)` and `(b, a, d)`:
//!
//! * `r(e)`: radius of the sphere through `a, b, c, d` (length). With `u = b - a`,
//!   `v = c - a`, `w = d - a`, the centre is
//!   `a + (|u|² (v × w) + |v|² (w × u) + |w|² (u × v)) / (2 u · (v × w))` (paper Sec. 4.2).
//! * `p(e) = (area(abc) + area(abd)) / 3` (area), so that `Σ p(e)` is the total area of a
//!   closed manifold mesh.
//! * `K_raw = Σ p(e) / r(e)` (length), the discrete form of `∫ dA / r` (paper Eq. 8 times S).
//!
//! Edge classes, decided on the geometry with the tolerances of [`Tolerances`]:
//!
//! * **flat**: bending angle `φ ≤ flat_angle`; the sphere is a plane, `r = ∞`, contributes 0.
//! * **ill-conditioned**: nearly coplanar (`min(φ, π - φ) < ill_angle`) *and* nearly
//!   co-circular (the circumcentres of the two triangles lie within `ill_cocircular · |e|`
//!   of each other). The sphere through four such points is 0/0: a perturbation of the
//!   size of rounding noise moves `r` anywhere between the circle's radius and infinity.
//!   The circumsphere estimator still uses it (and counts the edge); `Hybrid` uses the
//!   dihedral value there.
//! * **degenerate**: an incident triangle has zero area, the edge has zero length, or both
//!   triangles share their third vertex; contributes 0.
//! * **boundary** (one incident triangle) and **non-manifold** (three or more) edges have
//!   no pair of triangles: they are skipped and counted. Their faces' areas still count in
//!   the total area.
//!
//! The dihedral estimate of `p(e)/r(e)` is `φ · |e| / 2` with `φ` the bending angle
//! (π minus the interior dihedral angle, winding independent). Its sum is the integral of
//! the mean curvature, which equals `∫ dA / r` on a sphere.

use glam::DVec3;
use rayon::prelude::*;

use crate::adjacency::{BlockEdges, is_index_degenerate, map_edge_blocks};
use crate::error::{MeshError, VertexIndex, check_extent, check_finite, check_indices};
use crate::reduce::{SUM_CHUNK, deterministic_sum_parts};
use crate::weld::weld_identical;

/// Which per-edge estimate of `p(e) / r(e)` to sum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// The paper's sphere through the four vertices of the edge's two triangles.
    Circumsphere,
    /// `φ · |e| / 2`, the discrete mean-curvature integral.
    Dihedral,
    /// Circumsphere, with the dihedral value on ill-conditioned edges.
    Hybrid,
}

/// Thresholds of the edge classification; all dimensionless.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// Bending angle (radians) at or below which an edge is flat.
    pub flat_angle: f64,
    /// Bending angle (radians) from 0 or π below which an edge may be ill-conditioned.
    pub ill_angle: f64,
    /// Distance between the two triangles' circumcentres, relative to the edge length,
    /// below which an edge may be ill-conditioned.
    pub ill_cocircular: f64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances {
            flat_angle: 1e-12,
            ill_angle: 1e-3,
            ill_cocircular: 1e-3,
        }
    }
}

/// Class of one edge; the discriminants are the codes returned to Python.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum EdgeKind {
    Curved = 0,
    Flat = 1,
    IllConditioned = 2,
    Boundary = 3,
    NonManifold = 4,
    Degenerate = 5,
}

/// Geometry of one interior edge's pair of triangles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeGeometry {
    pub kind: EdgeKind,
    /// `1 / r`, the circumsphere's curvature (1 / length); 0 for flat and degenerate
    /// edges (`r = ∞`).
    pub curvature: f64,
    /// `p(e)`, a third of the two triangles' areas (area).
    pub weight: f64,
    /// `|n1 × n2|²` and `-n1 · n2` for the normals `n1 = u × v`, `n2 = u × w`: the bending
    /// angle is `atan2` of `sqrt(bend_sin_squared)` and `bend_cos` (area² · sin φ and
    /// area² · cos φ, up to a factor 4). Squared, so that classifying costs no root.
    bend_sin_squared: f64,
    bend_cos: f64,
    /// `|u|²`, the squared edge length (area).
    length_squared: f64,
}

/// Circumcentre of the triangle `(0, u, v)`, relative to its first corner.
#[inline]
#[must_use]
fn circumcentre_offset(u: DVec3, v: DVec3, n: DVec3) -> DVec3 {
    (v.length_squared() * n.cross(u) + u.length_squared() * v.cross(n)) / (2.0 * n.length_squared())
}

/// The sines that the classification compares with, computed once per mesh.
#[derive(Debug, Clone, Copy)]
struct Thresholds {
    /// `sin(flat_angle)`.
    sin_flat: f64,
    /// `sin(ill_angle)`.
    sin_ill: f64,
    ill_cocircular: f64,
}

impl From<&Tolerances> for Thresholds {
    fn from(tol: &Tolerances) -> Self {
        Thresholds {
            sin_flat: tol.flat_angle.sin(),
            sin_ill: tol.ill_angle.sin(),
            ill_cocircular: tol.ill_cocircular,
        }
    }
}

/// Classifies the edge `a b` with opposite vertices `c` and `d`, and computes its sphere.
#[must_use]
pub fn edge_geometry(a: DVec3, b: DVec3, c: DVec3, d: DVec3, tol: &Tolerances) -> EdgeGeometry {
    classify(a, b, c, d, &Thresholds::from(tol))
}

/// [`edge_geometry`] with the thresholds' sines already computed.
#[inline]
#[must_use]
fn classify(a: DVec3, b: DVec3, c: DVec3, d: DVec3, tol: &Thresholds) -> EdgeGeometry {
    let (u, v, w) = (b - a, c - a, d - a);
    let (n1, n2) = (u.cross(v), u.cross(w));
    let (l1, l2) = (n1.length(), n2.length());
    let length_squared = u.length_squared();
    let bend_cos = -n1.dot(n2);
    let mut g = EdgeGeometry {
        kind: EdgeKind::Degenerate,
        curvature: 0.0,
        // `(l1 + l2) / 6`; a product, as a division costs several.
        weight: (l1 + l2) * (1.0 / 6.0),
        bend_sin_squared: 0.0,
        bend_cos,
        length_squared,
    };
    // `sqrt` is exact at 0: these are the tests `|u| == 0`, `l1 == 0`, `l2 == 0`.
    if length_squared == 0.0 || l1 == 0.0 || l2 == 0.0 || c == d {
        return g;
    }
    g.bend_sin_squared = n1.cross(n2).length_squared();
    // φ ≤ flat_angle  ⇔  cos φ > 0 and sin φ ≤ sin(flat_angle), without an atan2; the sines
    // compared squared, without a root.
    let scale = l1 * l2;
    let flat = tol.sin_flat * scale;
    if bend_cos > 0.0 && g.bend_sin_squared <= flat * flat {
        g.kind = EdgeKind::Flat;
        return g;
    }
    // Centre offset `num / (2 det)`, so `1 / r = 2 |det| / |num|`: one division. With
    // `det = 0` (coplanar) the sphere is a plane: `r = ∞`.
    let vxw = v.cross(w);
    let det = u.dot(vxw);
    let num = length_squared * vxw + v.length_squared() * w.cross(u) + w.length_squared() * n1;
    let num_length = num.length();
    if num_length > 0.0 {
        let curvature = 2.0 * det.abs() / num_length;
        if curvature.is_finite() {
            g.curvature = curvature;
        }
    }
    // min(φ, π - φ) < ill_angle  ⇔  sin φ < sin(ill_angle) (for ill_angle < π/2).
    let ill = tol.sin_ill * scale;
    let near_coplanar = g.bend_sin_squared < ill * ill;
    g.kind = if near_coplanar
        && (circumcentre_offset(u, v, n1) - circumcentre_offset(u, w, n2)).length()
            < tol.ill_cocircular * length_squared.sqrt()
    {
        EdgeKind::IllConditioned
    } else {
        EdgeKind::Curved
    };
    g
}

impl EdgeGeometry {
    /// Circumsphere radius `r` (length); `∞` for flat and degenerate edges.
    #[inline]
    #[must_use]
    pub fn radius(&self) -> f64 {
        1.0 / self.curvature
    }

    /// Bending angle `φ = π - dihedral angle`, in `[0, π]` (radians); winding independent.
    #[inline]
    #[must_use]
    pub fn bending(&self) -> f64 {
        self.bend_sin_squared.sqrt().atan2(self.bend_cos)
    }

    /// Edge length `|u|` (length).
    #[inline]
    #[must_use]
    pub fn length(&self) -> f64 {
        self.length_squared.sqrt()
    }

    /// This edge's estimate of `p(e) / r(e)` (length).
    #[inline]
    #[must_use]
    pub fn contribution(&self, estimator: Estimator) -> f64 {
        match (self.kind, estimator) {
            (EdgeKind::Curved | EdgeKind::IllConditioned, Estimator::Circumsphere)
            | (EdgeKind::Curved, Estimator::Hybrid) => self.weight * self.curvature,
            (EdgeKind::Curved | EdgeKind::IllConditioned, _) => {
                self.bending() * self.length() / 2.0
            }
            _ => 0.0,
        }
    }
}

/// Per-edge arrays, when asked for.
#[derive(Debug, Clone, Default)]
pub struct EdgeArrays {
    /// Vertex pair `(lo, hi)` in the caller's indexing (after welding, the smallest index
    /// of each set of identical vertices).
    pub vertices: Vec<[u32; 2]>,
    pub kind: Vec<u8>,
    pub radius: Vec<f64>,
    pub weight: Vec<f64>,
    pub contribution: Vec<f64>,
}

/// Everything `shape_complexity` measures on one mesh.
#[derive(Debug, Clone)]
pub struct Complexity {
    /// `Σ contribution`, in the mesh's length unit.
    pub k_raw: f64,
    /// Total area of all faces.
    pub area: f64,
    /// Bounding box of the vertices referenced by faces.
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    pub edges: usize,
    pub interior_edges: usize,
    pub boundary_edges: usize,
    pub nonmanifold_edges: usize,
    pub flat_edges: usize,
    pub ill_conditioned_edges: usize,
    pub degenerate_edges: usize,
    pub merged_vertices: usize,
    /// Faces that repeat a vertex index (after welding); left out of the edge table.
    pub degenerate_faces: usize,
    pub per_edge: Option<EdgeArrays>,
}

#[inline]
#[must_use]
fn point(vertices: &[[f64; 3]], i: u32) -> DVec3 {
    DVec3::from_array(vertices[i as usize])
}

/// True when every face index lies in `0..vertex_count` (one parallel pass).
fn indices_in_range<I: VertexIndex>(faces: &[[I; 3]], vertex_count: usize) -> bool {
    faces
        .par_chunks(SUM_CHUNK)
        .all(|c| c.iter().flatten().all(|i| i.to_usize() < vertex_count))
}

/// One block's share of the edge pass: its contributions in edge order, its class counts,
/// its share of the total area (each incident face's `area / 3`, summed in edge order),
/// the box of its edges' endpoints and, when asked for, its per-edge arrays.
struct BlockTerms {
    contributions: Vec<f64>,
    count: [usize; 6],
    area: f64,
    box_min: DVec3,
    box_max: DVec3,
    per_edge: Option<EdgeArrays>,
}

/// Edges per batch of [`block_terms`].
const GATHER_BATCH: usize = 32;

/// Classifies and measures the edges of one block.
///
/// The edges' far vertices (`hi` and both opposite vertices) lie anywhere in the vertex
/// array: their loads miss the cache. They are read for a batch of edges first, loads that
/// do not wait for one another, and the batch is then measured from the copies: the misses
/// overlap instead of each stalling a long chain of arithmetic.
///
/// Every face that does not repeat a vertex index has three edges, so the total area is
/// the sum over edges of a third of their incident faces' areas (an interior edge's
/// `p(e)`), and the box of the referenced vertices is the box of the edges' endpoints:
/// the edge pass measures both, without a pass of its own over the faces.
fn block_terms(
    vertices: &[[f64; 3]],
    block: BlockEdges<'_>,
    estimator: Estimator,
    tol: &Thresholds,
    per_edge: bool,
) -> BlockTerms {
    let mut out = BlockTerms {
        contributions: Vec::with_capacity(block.len()),
        count: [0; 6],
        area: 0.0,
        box_min: DVec3::INFINITY,
        box_max: DVec3::NEG_INFINITY,
        per_edge: per_edge.then(EdgeArrays::default),
    };
    let mut corners = [[DVec3::ZERO; 4]; GATHER_BATCH];
    for first in (0..block.len()).step_by(GATHER_BATCH) {
        let batch = first..(first + GATHER_BATCH).min(block.len());
        for (e, p) in batch.clone().zip(&mut corners) {
            let [lo, hi] = block.edges[e];
            p[0] = point(vertices, lo);
            p[1] = point(vertices, hi);
            if let &[c, d] = block.incident(e) {
                p[2] = point(vertices, c);
                p[3] = point(vertices, d);
            }
        }
        for (e, p) in batch.zip(&corners) {
            out.box_min = out.box_min.min(p[0]).min(p[1]);
            out.box_max = out.box_max.max(p[0]).max(p[1]);
            let incident = block.incident(e);
            let g = (incident.len() == 2).then(|| classify(p[0], p[1], p[2], p[3], tol));
            let kind = match &g {
                Some(g) => {
                    out.area += g.weight;
                    g.kind
                }
                None => {
                    let u = p[1] - p[0];
                    for &o in incident {
                        out.area += u.cross(point(vertices, o) - p[0]).length() * (1.0 / 6.0);
                    }
                    if incident.len() == 1 {
                        EdgeKind::Boundary
                    } else {
                        EdgeKind::NonManifold
                    }
                }
            };
            out.count[kind as usize] += 1;
            out.contributions
                .push(g.map_or(0.0, |g| g.contribution(estimator)));
            if let Some(arrays) = &mut out.per_edge {
                arrays.vertices.push(block.edges[e]);
                arrays.kind.push(kind as u8);
                arrays.radius.push(g.map_or(f64::NAN, |g| g.radius()));
                arrays.weight.push(g.map_or(f64::NAN, |g| g.weight));
            }
        }
    }
    out
}

/// Shape complexity of a triangle mesh (paper Sec. 4.2). See the module docs for the math.
/// Faces come as `u32` or `i64` indices ([`VertexIndex`]), checked here.
///
/// Passes: the vertices' finiteness; the faces' indices; the weld; then the edge table
/// block by block ([`map_edge_blocks`]), each block's edges classified and measured while
/// in cache, with the area and the box. The result is the same to the bit for any number
/// of threads: K is a sum in fixed chunks of the edge order, the area a sum over the
/// blocks, each in edge order.
pub fn shape_complexity<I: VertexIndex>(
    vertices: &[[f64; 3]],
    faces: &[[I; 3]],
    estimator: Estimator,
    merge_vertices: bool,
    per_edge: bool,
    tol: &Tolerances,
) -> Result<Complexity, MeshError> {
    if vertices.is_empty() || faces.is_empty() {
        return Err(MeshError::Empty(format!(
            "mesh is empty ({} vertices, {} faces)",
            vertices.len(),
            faces.len()
        )));
    }
    let all_finite = vertices.par_chunks(SUM_CHUNK).all(|c| {
        c.iter()
            .all(|v| v[0].is_finite() & v[1].is_finite() & v[2].is_finite())
    });
    if !all_finite {
        check_finite(vertices)?;
    }
    if !indices_in_range(faces, vertices.len()) {
        check_indices(faces, vertices.len())?;
    }
    if merge_vertices {
        let weld = weld_identical(vertices);
        if weld.merged > 0 {
            let c = &weld.canonical;
            let remapped: Vec<[u32; 3]> = faces
                .par_iter()
                .with_min_len(1 << 12)
                .map(|f| [c[f[0].to_usize()], c[f[1].to_usize()], c[f[2].to_usize()]])
                .collect();
            return edge_pass(vertices, &remapped, weld.merged, estimator, per_edge, tol);
        }
    }
    edge_pass(vertices, faces, 0, estimator, per_edge, tol)
}

/// The rest of [`shape_complexity`] on index-checked (and welded) faces.
fn edge_pass<I: VertexIndex>(
    vertices: &[[f64; 3]],
    faces: &[[I; 3]],
    merged_vertices: usize,
    estimator: Estimator,
    per_edge: bool,
    tol: &Tolerances,
) -> Result<Complexity, MeshError> {
    let tol = Thresholds::from(tol);
    let (mut blocks, degenerate_faces) = map_edge_blocks(faces, vertices.len(), |block| {
        block_terms(vertices, block, estimator, &tol, per_edge)
    })?;
    let area: f64 = blocks.iter().map(|b| b.area).sum();
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for b in &blocks {
        lo = lo.min(b.box_min);
        hi = hi.max(b.box_max);
    }
    if degenerate_faces > 0 {
        // Faces that repeat an index have no edges; their vertices are referenced still.
        for f in faces {
            let t = f.map(|i| i.to_usize() as u32);
            if is_index_degenerate(&t) {
                for i in t {
                    lo = lo.min(point(vertices, i));
                    hi = hi.max(point(vertices, i));
                }
            }
        }
    }
    let (bbox_min, bbox_max) = (lo.to_array(), hi.to_array());
    check_extent(bbox_min, bbox_max)?;
    if area.is_nan() || area <= 0.0 {
        return Err(MeshError::Empty(match faces.len() {
            1 => "mesh has zero surface area: its only face is degenerate".to_string(),
            n => format!("mesh has zero surface area: all {n} faces are degenerate"),
        }));
    }
    let contributions: Vec<Vec<f64>> = blocks
        .iter_mut()
        .map(|b| std::mem::take(&mut b.contributions))
        .collect();
    let k_raw = deterministic_sum_parts(&contributions);
    let mut count = [0usize; 6];
    for b in &blocks {
        for (total, c) in count.iter_mut().zip(b.count) {
            *total += c;
        }
    }
    let edges: usize = count.iter().sum();
    let per_edge = per_edge.then(|| {
        let mut arrays = EdgeArrays {
            vertices: Vec::with_capacity(edges),
            kind: Vec::with_capacity(edges),
            radius: Vec::with_capacity(edges),
            weight: Vec::with_capacity(edges),
            contribution: contributions.concat(),
        };
        for b in blocks.iter_mut().filter_map(|b| b.per_edge.take()) {
            arrays.vertices.extend(b.vertices);
            arrays.kind.extend(b.kind);
            arrays.radius.extend(b.radius);
            arrays.weight.extend(b.weight);
        }
        arrays
    });
    let boundary_edges = count[EdgeKind::Boundary as usize];
    let nonmanifold_edges = count[EdgeKind::NonManifold as usize];
    Ok(Complexity {
        k_raw,
        area,
        bbox_min,
        bbox_max,
        edges,
        interior_edges: edges - boundary_edges - nonmanifold_edges,
        boundary_edges,
        nonmanifold_edges,
        flat_edges: count[EdgeKind::Flat as usize],
        ill_conditioned_edges: count[EdgeKind::IllConditioned as usize],
        degenerate_edges: count[EdgeKind::Degenerate as usize],
        merged_vertices,
        degenerate_faces,
        per_edge,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tol() -> Tolerances {
        Tolerances::default()
    }

    #[test]
    fn meshes_wider_than_the_supported_extent_are_refused() {
        let v = [
            [0.0, 0.0, 0.0],
            [1e308, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let f = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let err = shape_complexity::<u32>(&v, &f, Estimator::Circumsphere, true, false, &tol());
        assert!(matches!(err, Err(MeshError::Parameter(_))), "{err:?}");
    }

    #[test]
    fn four_points_on_unit_sphere_give_radius_one() {
        let a = DVec3::new(1.0, 0.0, 0.0);
        let b = DVec3::new(0.0, 1.0, 0.0);
        let c = DVec3::new(0.0, 0.0, 1.0);
        let d = DVec3::new(0.0, -0.6, -0.8);
        let g = edge_geometry(a, b, c, d, &tol());
        assert_eq!(g.kind, EdgeKind::Curved);
        assert!((g.radius() - 1.0).abs() < 1e-12, "{}", g.radius());
    }

    #[test]
    fn flat_square_is_flat_and_noisy_square_is_ill_conditioned() {
        let a = DVec3::new(0.0, 0.0, 0.0);
        let b = DVec3::new(1.0, 1.0, 0.0);
        let c = DVec3::new(1.0, 0.0, 0.0);
        let d = DVec3::new(0.0, 1.0, 0.0);
        assert_eq!(edge_geometry(a, b, c, d, &tol()).kind, EdgeKind::Flat);
        let noisy = edge_geometry(a, b, c, d + DVec3::new(0.0, 0.0, 1e-9), &tol());
        assert_eq!(noisy.kind, EdgeKind::IllConditioned);
        assert!(noisy.contribution(Estimator::Hybrid) < 1e-8);
    }

    #[test]
    fn winding_does_not_change_the_bending_angle() {
        let a = DVec3::new(0.0, 0.0, 0.0);
        let b = DVec3::new(1.0, 0.0, 0.0);
        let c = DVec3::new(0.5, 1.0, 0.2);
        let d = DVec3::new(0.4, -1.0, 0.3);
        let g1 = edge_geometry(a, b, c, d, &tol());
        let g2 = edge_geometry(b, a, d, c, &tol());
        assert!((g1.bending() - g2.bending()).abs() < 1e-14);
        assert!((g1.radius() - g2.radius()).abs() < 1e-12 * g1.radius());
    }

    /// The area and box measured by the edge pass equal a plain pass over the faces, with
    /// boundary and non-manifold edges, a repeated face, and a face that repeats an index
    /// and is the only one to reference its far vertex.
    #[test]
    fn edge_pass_area_and_box_match_the_faces() {
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.3, -0.7, 0.4],
            [-2.0, 5.0, 9.0],
        ];
        let f: [[u32; 3]; 7] = [
            [0, 2, 1],
            [0, 1, 3],
            [0, 3, 2],
            [1, 2, 3],
            [0, 1, 4],
            [0, 1, 4],
            [5, 5, 2],
        ];
        let c = shape_complexity(&v, &f, Estimator::Circumsphere, true, false, &tol()).unwrap();
        let p = |i: u32| DVec3::from_array(v[i as usize]);
        let area: f64 = f
            .iter()
            .map(|t| (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length() / 2.0)
            .sum();
        assert!((c.area - area).abs() <= 1e-14 * area, "{} {area}", c.area);
        assert_eq!(c.bbox_min, [-2.0, -0.7, 0.0]);
        assert_eq!(c.bbox_max, [1.0, 5.0, 9.0]);
        assert_eq!(c.degenerate_faces, 1);
        assert_eq!(c.nonmanifold_edges, 1);
    }

    #[test]
    fn shared_third_vertex_is_degenerate() {
        let a = DVec3::ZERO;
        let b = DVec3::X;
        let c = DVec3::Y;
        assert_eq!(edge_geometry(a, b, c, c, &tol()).kind, EdgeKind::Degenerate);
    }
}
