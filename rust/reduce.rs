//! Reductions whose result does not depend on the number of threads: sums in fixed chunks
//! and the bounding box of the referenced vertices. K, the area and the Hausdorff
//! statistics are sums of millions of terms; a sum split by rayon's work stealing would
//! round differently from run to run, so sums go through [`deterministic_sum`].

use glam::DVec3;
use rayon::prelude::*;

/// Edges per chunk of the fixed-order parallel sum (keeps results thread-count independent).
pub const SUM_CHUNK: usize = 1 << 12;

/// Sums in fixed chunks so the result does not depend on the number of threads.
#[must_use]
pub fn deterministic_sum(values: &[f64]) -> f64 {
    let partial: Vec<f64> = values
        .par_chunks(SUM_CHUNK)
        .map(|c| c.iter().sum::<f64>())
        .collect();
    partial.iter().sum()
}

/// [`deterministic_sum`] of the concatenation of `parts`, to the bit, without building
/// it: every chunk of [`SUM_CHUNK`] consecutive values is summed in order across the parts
/// it straddles.
#[must_use]
pub fn deterministic_sum_parts(parts: &[Vec<f64>]) -> f64 {
    let mut ends = Vec::with_capacity(parts.len());
    let mut total = 0;
    for p in parts {
        total += p.len();
        ends.push(total);
    }
    let partial: Vec<f64> = (0..total.div_ceil(SUM_CHUNK))
        .into_par_iter()
        .map(|c| {
            let (begin, end) = (c * SUM_CHUNK, ((c + 1) * SUM_CHUNK).min(total));
            // The first part holding index `begin`, then on through the following parts.
            let first = ends.partition_point(|&e| e <= begin);
            let offset = begin - (ends[first] - parts[first].len());
            parts[first..]
                .iter()
                .flatten()
                .skip(offset)
                .take(end - begin)
                .sum::<f64>()
        })
        .collect();
    partial.iter().sum()
}

/// Centre of the box `[lo, hi]`, also when `lo + hi` overflows (a box near ±1.8e308):
/// `(lo + hi) / 2` otherwise, to the bit.
#[must_use]
pub fn bbox_centre(lo: [f64; 3], hi: [f64; 3]) -> DVec3 {
    let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
    let centre = (lo + hi) * 0.5;
    if centre.is_finite() {
        centre
    } else {
        lo * 0.5 + hi * 0.5
    }
}

/// Axis-aligned bounding box of the vertices that some face references.
#[must_use]
pub fn referenced_bbox(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> ([f64; 3], [f64; 3]) {
    let (lo, hi) = faces
        .par_iter()
        .fold(
            || (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(lo, hi), f| {
                f.iter().fold((lo, hi), |(lo, hi), &i| {
                    let p = DVec3::from_array(vertices[i as usize]);
                    (lo.min(p), hi.max(p))
                })
            },
        )
        .reduce(
            || (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        );
    (lo.to_array(), hi.to_array())
}

/// The smallest widening in [`overlap_pad`] (length): a thousand times the smallest normal
/// f32, above the outward rounding of the BVH's f32 boxes near zero (a mesh `1e-38` long
/// scored 617 boxes per point on one triangle when its pads were subnormal).
const MIN_OVERLAP_PAD: f64 = 1e3 * f32::MIN_POSITIVE as f64;

/// The widening of every box in [`box_overlap`], per axis, for a mesh whose box has sides
/// `extent`: `1e-3 × extent_axis` (at least `1e-8` of the largest side, so a flat mesh's
/// zero side is counted). Per axis, the overlap does not change when an axis is scaled: a
/// mesh long on one axis (two parts far apart along x) does not widen its thin axes by its
/// length. `None` for a mesh of one point (or a non-finite extent).
#[must_use]
pub fn overlap_pad(extent: DVec3) -> Option<DVec3> {
    let largest = extent.max_element();
    if !(largest > 0.0 && largest.is_finite()) {
        return None;
    }
    Some((1e-3 * extent.max(DVec3::splat(1e-5 * largest))).max(DVec3::splat(MIN_OVERLAP_PAD)))
}

/// How many triangle bounding boxes a point of the mesh's bounding box lies in, on average
/// (dimensionless): `sum over faces of vol(box_f + pad) / vol(box + pad)`, every box
/// widened by [`overlap_pad`] (1e-3 of the mesh's side on each axis) so flat boxes count.
/// A BVH query visits about this many triangles beyond the few near it. 0 for a mesh of
/// one point. Indices must be in range (checked by the caller).
#[must_use]
pub fn box_overlap(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
    if faces.is_empty() {
        return 0.0;
    }
    let (lo, hi) = referenced_bbox(vertices, faces);
    let extent = DVec3::from_array(hi) - DVec3::from_array(lo);
    let Some(pad) = overlap_pad(extent) else {
        return 0.0;
    };
    let volumes: Vec<f64> = faces
        .par_chunks(SUM_CHUNK)
        .map(|chunk| {
            chunk
                .iter()
                .map(|f| {
                    let [a, b, c] = f.map(|i| DVec3::from_array(vertices[i as usize]));
                    let side = a.max(b).max(c) - a.min(b).min(c) + pad;
                    side.x * side.y * side.z
                })
                .sum::<f64>()
        })
        .collect();
    let whole = extent + pad;
    volumes.iter().sum::<f64>() / (whole.x * whole.y * whole.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_overlap_of_a_grid_and_of_a_fan() {
        // A flat n x n grid of the unit square: the boxes tile it, flat boxes padded.
        let n = 20u32;
        let (v, f) = crate::test_meshes::grid(n, |_, _| 0.0);
        let (pad, cell) = (1e-3, 1.0 / f64::from(n));
        let expected =
            2.0 * f64::from(n * n) * (cell + pad).powi(2) * pad / ((1.0 + pad).powi(2) * pad);
        assert!((box_overlap(&v, &f) - expected).abs() < 1e-12 * expected);
        // Every triangle of a fan over a circle spans the whole box.
        let m = 200;
        let mut fan = vec![[0.0, 0.0, 0.0]];
        for k in 0..m {
            let t = std::f64::consts::TAU * f64::from(k) / f64::from(m);
            fan.push([t.cos(), t.sin(), 0.5 * f64::from(k % 2)]);
        }
        let faces: Vec<[u32; 3]> = (1..m).map(|k| [0, k, k + 1]).collect();
        assert!(box_overlap(&fan, &faces) > 5.0);
        assert_eq!(box_overlap(&v, &[]), 0.0);
    }

    #[test]
    fn box_overlap_of_two_parts_far_apart_on_one_axis_is_that_of_one() {
        // Two copies of a grid 1e4 apart along x: a point of the long box lies in no
        // more boxes than a point of one copy's box (the empty middle adds none).
        let (v, f) = crate::test_meshes::grid(100, |x, y| 0.01 * (x * 7.0).sin() * y);
        let one = box_overlap(&v, &f);
        let mut v2 = v.clone();
        v2.extend(v.iter().map(|p| [p[0] + 1e4, p[1], p[2]]));
        let n = v.len() as u32;
        let mut f2 = f.clone();
        f2.extend(f.iter().map(|t| t.map(|i| i + n)));
        let two = box_overlap(&v2, &f2);
        assert!(two <= one, "{two} against {one}");
    }

    #[test]
    fn bbox_centre_of_a_box_near_the_float64_limit_is_finite() {
        assert_eq!(bbox_centre([0.0; 3], [2.0; 3]), DVec3::splat(1.0));
        assert_eq!(bbox_centre([-1e308; 3], [-1e308; 3]), DVec3::splat(-1e308));
        assert_eq!(
            bbox_centre([1e308; 3], [1.5e308; 3]),
            DVec3::splat(1.25e308)
        );
    }

    #[test]
    fn the_sum_does_not_depend_on_the_thread_count() {
        let values: Vec<f64> = (0..100_000).map(|i| 1.0 / (1.0 + f64::from(i))).collect();
        let sums: Vec<u64> = [1, 2, 3]
            .iter()
            .map(|&threads| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("a test pool");
                pool.install(|| deterministic_sum(&values)).to_bits()
            })
            .collect();
        assert!(sums.windows(2).all(|w| w[0] == w[1]));
    }

    #[test]
    fn the_sum_of_parts_is_the_sum_of_their_concatenation() {
        let values: Vec<f64> = (0..50_000).map(|i| 1.0 / (3.0 + f64::from(i))).collect();
        for sizes in [vec![50_000], vec![1, 4095, 4097, 0, 41_807], vec![123; 406]] {
            let mut parts = Vec::new();
            let mut rest = &values[..];
            for &s in &sizes {
                let s = s.min(rest.len());
                parts.push(rest[..s].to_vec());
                rest = &rest[s..];
            }
            parts.push(rest.to_vec());
            let sum = deterministic_sum_parts(&parts);
            assert_eq!(
                sum.to_bits(),
                deterministic_sum(&values).to_bits(),
                "{sizes:?}"
            );
        }
        assert_eq!(deterministic_sum_parts(&[]), deterministic_sum(&[]));
    }

    #[test]
    fn the_box_holds_only_referenced_vertices() {
        let vertices = [
            [0.0, 0.0, 0.0],
            [1.0, 2.0, 3.0],
            [-1.0, 0.5, 0.0],
            [9.0, 9.0, 9.0],
        ];
        let (lo, hi) = referenced_bbox(&vertices, &[[0, 1, 2]]);
        assert_eq!((lo, hi), ([-1.0, 0.0, 0.0], [1.0, 2.0, 3.0]));
    }
}
