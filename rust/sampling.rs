//! Seeded, area-weighted points on a mesh's surface.
//!
//! The sample set of a mesh, for a count `N` and a seed:
//!
//! 1. **Vertices**: every vertex that some face references, once, in index order.
//!    Unreferenced vertices are not on the surface and are never sampled.
//! 2. **Area samples**: exactly `N` points, spread over the faces by systematic sampling
//!    of the cumulative area: with `A` the total area, `C_i` the area of faces `0..i` and
//!    one offset `u ∈ [0, 1)` drawn from the seed, face `i` receives the `j` with
//!    `C_i ≤ (j + u) A / N < C_{i+1}`, that is `⌊N a_i / A⌋` or `⌈N a_i / A⌉` points (its
//!    expected share, rounded up or down at random). Zero-area faces receive none.
//!    Inside face `i`, the points are uniform by area: `(r₁, r₂)` uniform in `[0, 1)²`
//!    give `a + √r₁ (1 - r₂) (b - a) + √r₁ r₂ (c - a)`, with `r₁, r₂` drawn from a
//!    SplitMix64 stream seeded by a hash of `(seed, i)`.
//!
//! Each face has its own stream and the offsets are a prefix sum taken in a fixed order, so
//! the points do not depend on the number of threads. Points are computed in a caller-chosen
//! frame (`centre` subtracted from every vertex first) so that meshes far from the origin
//! keep their precision.

use glam::DVec3;
use rayon::prelude::*;

use crate::error::{MeshError, check_finite, check_indices};

/// Faces per parallel work unit.
const FACE_BLOCK: usize = 1 << 12;

/// SplitMix64 (Steele, Lea & Flood, "Fast splittable pseudorandom number generators",
/// OOPSLA 2014): a 64-bit state advanced by a constant and passed through a mixer.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

/// The SplitMix64 output function, a bijective 64-bit mixer.
#[inline]
#[must_use]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl SplitMix64 {
    const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

    #[must_use]
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// An independent stream for item `index` under `seed` (hashes both, so the streams
    /// of neighbouring items do not overlap).
    #[must_use]
    pub fn for_item(seed: u64, index: u64) -> Self {
        SplitMix64(mix64(seed ^ mix64(index.wrapping_add(Self::GAMMA))))
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(Self::GAMMA);
        mix64(self.0)
    }

    /// Uniform in `[0, 1)`, 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Vertices referenced by at least one face, sorted, each once.
#[must_use]
pub fn referenced_vertices(faces: &[[u32; 3]], vertex_count: usize) -> Vec<u32> {
    let mut used = vec![false; vertex_count];
    for f in faces {
        for &i in f {
            used[i as usize] = true;
        }
    }
    (0..vertex_count as u32)
        .filter(|&i| used[i as usize])
        .collect()
}

/// Corners of face `f`, with `centre` subtracted (length).
#[inline]
#[must_use]
pub fn local_corners(vertices: &[[f64; 3]], f: [u32; 3], centre: DVec3) -> [DVec3; 3] {
    f.map(|i| DVec3::from_array(vertices[i as usize]) - centre)
}

/// Area of each face (length²).
#[must_use]
pub fn face_areas(vertices: &[[f64; 3]], faces: &[[u32; 3]], centre: DVec3) -> Vec<f64> {
    faces
        .par_iter()
        .map(|&f| {
            let [a, b, c] = local_corners(vertices, f, centre);
            (b - a).cross(c - a).length() * 0.5
        })
        .collect()
}

/// Systematic allocation of `total` samples to faces by area: returns `offsets` of length
/// `faces + 1`, face `i` owning samples `offsets[i] .. offsets[i + 1]`. All zero when the
/// total area is zero.
#[must_use]
pub fn area_offsets(areas: &[f64], total: usize, seed: u64) -> Vec<usize> {
    let mut offsets = Vec::with_capacity(areas.len() + 1);
    offsets.push(0);
    let area: f64 = areas.iter().sum();
    if area.is_nan() || area <= 0.0 || total == 0 {
        offsets.resize(areas.len() + 1, 0);
        return offsets;
    }
    let u = SplitMix64::for_item(seed, u64::MAX).next_f64();
    let n = total as f64;
    let mut cumulative = 0.0;
    for &a in areas {
        cumulative += a;
        let reached = ((cumulative / area) * n - u).ceil().clamp(0.0, n) as usize;
        // Monotone even if rounding wobbles.
        offsets.push(reached.max(*offsets.last().unwrap_or(&0)));
    }
    if let Some(last) = offsets.last_mut() {
        *last = total;
    }
    offsets
}

/// The surface samples of a mesh. See the module docs.
#[derive(Debug, Clone, Default)]
pub struct SurfaceSamples {
    /// Points, in the frame with `centre` subtracted (length): vertex samples first, then
    /// area samples grouped by face.
    pub points: Vec<DVec3>,
    /// Index of the source vertex of each vertex sample (increasing).
    pub vertex_ids: Vec<u32>,
    /// `offsets[i] .. offsets[i + 1]` index the area samples of face `i`, counted from
    /// the first area sample.
    pub offsets: Vec<usize>,
    /// The centre subtracted from the points (length).
    pub centre: DVec3,
}

impl SurfaceSamples {
    /// Number of vertex samples (they come first).
    #[inline]
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.vertex_ids.len()
    }

    /// The same samples in the frame centred on `centre` (`p + self.centre - centre`;
    /// rounding of order 1e-16 of the coordinates).
    #[must_use]
    pub fn recentred(&self, centre: DVec3) -> SurfaceSamples {
        let shift = self.centre - centre;
        SurfaceSamples {
            points: self.points.par_iter().map(|p| *p + shift).collect(),
            vertex_ids: self.vertex_ids.clone(),
            offsets: self.offsets.clone(),
            centre,
        }
    }

    /// Face of each sample; `u32::MAX` for vertex samples.
    #[must_use]
    pub fn faces(&self) -> Vec<u32> {
        let mut out = vec![u32::MAX; self.vertex_count()];
        for (i, w) in self.offsets.windows(2).enumerate() {
            out.extend(std::iter::repeat_n(i as u32, w[1] - w[0]));
        }
        out
    }
}

/// Samples a mesh: its referenced vertices, then `area_samples` points by area, in the
/// frame centred on `centre`. See the module docs.
pub fn surface_samples(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    centre: DVec3,
    area_samples: usize,
    seed: u64,
) -> Result<SurfaceSamples, MeshError> {
    if faces.is_empty() {
        return Err(MeshError::Empty("mesh has no faces to sample".into()));
    }
    check_finite(vertices)?;
    check_indices(faces, vertices.len())?;
    let vertex_ids = referenced_vertices(faces, vertices.len());
    let offsets = area_offsets(&face_areas(vertices, faces, centre), area_samples, seed);
    let n_area = offsets[faces.len()];
    let mut points = Vec::new();
    let total = vertex_ids.len() + n_area;
    // A sample count is the caller's choice: one too large for memory is refused here,
    // not left to abort the process when the allocation fails.
    points.try_reserve_exact(total).map_err(|_| {
        MeshError::Parameter(format!(
            "{n_area} area samples need {:.1} GB for their positions alone, more than can \
             be allocated: ask for fewer samples",
            total.saturating_mul(std::mem::size_of::<DVec3>()) as f64 / 1e9
        ))
    })?;
    points.extend(
        vertex_ids
            .iter()
            .map(|&i| DVec3::from_array(vertices[i as usize]) - centre),
    );
    points.resize(vertex_ids.len() + n_area, DVec3::ZERO);
    // Split the area part into one slice per block of faces, then fill them in parallel.
    let mut rest = &mut points[vertex_ids.len()..];
    let mut blocks = Vec::with_capacity(faces.len().div_ceil(FACE_BLOCK));
    for start in (0..faces.len()).step_by(FACE_BLOCK) {
        let end = (start + FACE_BLOCK).min(faces.len());
        let (head, tail) = rest.split_at_mut(offsets[end] - offsets[start]);
        blocks.push((start, end, head));
        rest = tail;
    }
    blocks.into_par_iter().for_each(|(start, end, out)| {
        let mut k = 0;
        for face in start..end {
            let [a, b, c] = local_corners(vertices, faces[face], centre);
            let (ab, ac) = (b - a, c - a);
            let mut rng = SplitMix64::for_item(seed, face as u64);
            for _ in offsets[face]..offsets[face + 1] {
                let s = rng.next_f64().sqrt();
                let r2 = rng.next_f64();
                out[k] = a + ab * (s * (1.0 - r2)) + ac * (s * r2);
                k += 1;
            }
        }
    });
    Ok(SurfaceSamples {
        points,
        vertex_ids,
        offsets,
        centre,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_reference_values() {
        // First outputs of SplitMix64 seeded with 0 (reference implementation by Vigna).
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn offsets_follow_area_and_sum_to_the_total() {
        let areas = [1.0, 0.0, 2.0, 0.5, 0.5];
        for seed in 0..20 {
            let o = area_offsets(&areas, 1000, seed);
            assert_eq!(o.len(), 6);
            assert_eq!(o[5], 1000);
            assert_eq!(o[2] - o[1], 0);
            for (i, a) in areas.iter().enumerate() {
                let expected = 1000.0 * a / 4.0;
                let got = (o[i + 1] - o[i]) as f64;
                assert!((got - expected).abs() <= 1.0, "{seed} {i} {got} {expected}");
            }
        }
        assert_eq!(area_offsets(&[0.0, 0.0], 10, 0), vec![0, 0, 0]);
    }

    #[test]
    fn samples_lie_on_their_faces_and_skip_unreferenced_vertices() {
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [9.0, 9.0, 9.0],
            [0.0, 0.0, 1.0],
        ];
        let f = [[0, 1, 2], [0, 1, 4]];
        let s = surface_samples(&v, &f, DVec3::ZERO, 1000, 3).unwrap();
        assert_eq!(s.vertex_ids, vec![0, 1, 2, 4]);
        assert_eq!(s.points.len(), 1004);
        let faces = s.faces();
        for (p, &face) in s.points.iter().zip(&faces).skip(4) {
            let (x, y, z) = (p.x, p.y, p.z);
            match face {
                0 => assert!(z == 0.0 && x >= 0.0 && y >= 0.0 && x + y <= 1.0 + 1e-15),
                1 => assert!(y == 0.0 && x >= 0.0 && z >= 0.0 && x + z <= 1.0 + 1e-15),
                _ => panic!(),
            }
        }
        // Same seed, same points; another seed, other points.
        let again = surface_samples(&v, &f, DVec3::ZERO, 1000, 3).unwrap();
        assert_eq!(again.points, s.points);
        let other = surface_samples(&v, &f, DVec3::ZERO, 1000, 4).unwrap();
        assert_ne!(other.points, s.points);
    }

    #[test]
    fn uniform_by_area_inside_a_triangle() {
        // The mean of uniform points is the centroid; a quarter of them fall in the
        // sub-triangle at corner a with half the sides.
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let s = surface_samples(&v, &[[0, 1, 2]], DVec3::ZERO, 200_000, 1).unwrap();
        let area = &s.points[3..];
        let mean = area.iter().fold(DVec3::ZERO, |m, p| m + *p) / area.len() as f64;
        assert!((mean - DVec3::new(1.0 / 3.0, 1.0 / 3.0, 0.0)).length() < 3e-3);
        let corner = area.iter().filter(|p| p.x + p.y < 0.5).count() as f64 / area.len() as f64;
        assert!((corner - 0.25).abs() < 5e-3, "{corner}");
    }
}
