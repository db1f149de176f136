//! The one-sided sampled distance from a source mesh to a target tree: the samples
//! measured ([`super::exact`]), their statistics, the certified bound ([`super::bound`]),
//! and the closest point of the maximum.

use glam::DVec3;
use rayon::prelude::*;

use super::bound::{Bounds, Lower, Source, certify};
use super::exact::measure;
use super::options::{Options, check_tolerance};
use super::statistics::{Statistics, statistics};
use crate::bvh::TriangleTree;
use crate::error::{MAX_EXTENT, MeshError, check_finite, check_indices};
use crate::sampling::{SurfaceSamples, surface_samples};

/// Per-sample output.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleData {
    /// Sample points, caller's frame (length).
    pub points: Vec<[f64; 3]>,
    /// Face of the source each sample lies on (`u32::MAX` for vertex samples).
    pub faces: Vec<u32>,
    /// Exact distance of each sample (length).
    pub distances: Vec<f64>,
    /// Distance of each source vertex (length); NaN for unreferenced vertices.
    pub vertex_distances: Vec<f64>,
}

/// The one-sided distance from a source mesh to a target tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Directed {
    pub n_samples: usize,
    pub n_vertex_samples: usize,
    /// Largest exact distance found at any evaluated point (samples, and refinement points
    /// with a tolerance): a lower bound on `h(A, B)` (length).
    pub max: f64,
    /// The point achieving `max` (caller's frame), its closest point on the target, and
    /// the target face holding it.
    pub argmax: [f64; 3],
    pub argmax_closest: [f64; 3],
    pub argmax_face: u32,
    pub statistics: Option<Statistics>,
    pub bounds: Option<Bounds>,
    pub samples: Option<SampleData>,
}

/// The one-sided sampled distance from the source mesh to `tree`. See the
/// [module docs](super).
pub fn directed(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    tree: &TriangleTree,
    opts: &Options,
) -> Result<Directed, MeshError> {
    if faces.is_empty() || vertices.is_empty() {
        return Err(MeshError::Empty("the source mesh has no faces".into()));
    }
    if tree.is_empty() {
        return Err(MeshError::Empty("the target mesh has no faces".into()));
    }
    check_finite(vertices)?;
    check_indices(faces, vertices.len())?;
    check_tolerance(opts)?;
    let samples = surface_samples(vertices, faces, tree.centre(), opts.area_samples, opts.seed)?;
    directed_from_samples(vertices, faces, &samples, tree, opts)
}

/// [`directed`] with the source's samples given (drawn with [`surface_samples`] from
/// `vertices` and `faces`, in any frame): a mesh measured against several targets is
/// sampled once. `opts.area_samples` and `opts.seed` are not used.
pub fn directed_from_samples(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    samples: &SurfaceSamples,
    tree: &TriangleTree,
    opts: &Options,
) -> Result<Directed, MeshError> {
    if tree.is_empty() {
        return Err(MeshError::Empty("the target mesh has no faces".into()));
    }
    check_tolerance(opts)?;
    if samples.offsets.len() != faces.len() + 1 {
        return Err(MeshError::Parameter(format!(
            "the samples were drawn from a mesh of {} faces, not {}",
            samples.offsets.len().saturating_sub(1),
            faces.len()
        )));
    }
    let centre = tree.centre();
    let recentred;
    let samples = if samples.centre == centre {
        samples
    } else {
        recentred = samples.recentred(centre);
        &recentred
    };
    let points = &samples.points;
    if let Some((_, far)) = tree.beyond_reach(&points[..samples.vertex_count()]) {
        return Err(MeshError::Parameter(format!(
            "a vertex of one mesh lies {far:.3e} (length) from the centre of the other: more \
             than the supported {MAX_EXTENT:.0e}"
        )));
    }
    let nv = samples.vertex_count();
    let bounds_wanted =
        opts.bounds || opts.tolerance.is_some() || opts.relative_tolerance.is_some();
    // Exact distances where needed: every sample (return_samples); the vertices (bounds);
    // the area samples (statistics, which describe the surface: area samples only). The
    // rest only has to show it cannot raise the maximum.
    let na = points.len() - nv;
    let vertices_exact = opts.return_samples || bounds_wanted || (opts.statistics && na == 0);
    let area_exact = opts.return_samples || opts.statistics;
    let (exact_d2, vertex_slots, best) = measure(tree, points, nv, vertices_exact, area_exact);
    let mut lower = Lower {
        best,
        point: points[best.index],
    };

    // Per-vertex distances (NaN: unreferenced), from the exact vertex samples.
    let vertex_distances = vertices_exact.then(|| {
        let mut out = vec![f64::NAN; vertices.len()];
        for (k, &v) in samples.vertex_ids.iter().enumerate() {
            out[v as usize] = exact_d2[k].sqrt();
        }
        out
    });
    let bounds = bounds_wanted.then(|| {
        let distances = vertex_distances.as_ref();
        let distances = distances.expect("vertex distances are exact with bounds");
        let ids = &samples.vertex_ids;
        let source = Source::new(vertices, faces, centre, distances, ids, &vertex_slots);
        certify(tree, &source, opts, &mut lower, points.len())
    });

    // The area samples' distances (the vertices' when there are none); `exact_d2` starts
    // at the area samples unless the vertices were measured exactly too.
    let statistics = opts.statistics.then(|| {
        let first = if vertices_exact && na > 0 { nv } else { 0 };
        let d: Vec<f64> = exact_d2[first..].par_iter().map(|d2| d2.sqrt()).collect();
        statistics(&d)
    });
    let sample_data = opts.return_samples.then(|| SampleData {
        points: points
            .par_iter()
            .map(|p| (*p + centre).to_array())
            .collect(),
        faces: samples.faces(),
        distances: exact_d2.par_iter().map(|d2| d2.sqrt()).collect(),
        vertex_distances: vertex_distances.clone().unwrap_or_default(),
    });
    Ok(with_closest(
        tree,
        &lower,
        points.len(),
        nv,
        statistics,
        bounds,
        sample_data,
    ))
}

/// The result, with the closest point of the maximum searched again in full (the
/// deterministic tie-break).
fn with_closest(
    tree: &TriangleTree,
    lower: &Lower,
    n_samples: usize,
    n_vertex_samples: usize,
    statistics: Option<Statistics>,
    bounds: Option<Bounds>,
    samples: Option<SampleData>,
) -> Directed {
    let centre: DVec3 = tree.centre();
    let hit = tree
        .nearest_local(lower.point, u32::MAX, 0.0, &mut tree.stack())
        .expect("tree is not empty");
    debug_assert_eq!(hit.d2, lower.best.d2);
    Directed {
        n_samples,
        n_vertex_samples,
        max: lower.best.d2.sqrt(),
        argmax: (lower.point + centre).to_array(),
        argmax_closest: (hit.point + centre).to_array(),
        argmax_face: hit.face,
        statistics,
        bounds,
        samples,
    }
}
