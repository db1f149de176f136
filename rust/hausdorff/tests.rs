//! The one-sided distance end to end: parallel squares, a bump refined to a tolerance, a
//! relative tolerance, a threshold, samples drawn once, collapsed sources, max-only
//! against full statistics.

use glam::DVec3;

use super::statistics::statistics;
use super::{Options, RELATIVE_FLOOR, directed, directed_from_samples};
use crate::bvh::TriangleTree;
use crate::sampling::surface_samples;

fn options() -> Options {
    Options {
        area_samples: 2000,
        seed: 1,
        statistics: true,
        bounds: true,
        tolerance: None,
        relative_tolerance: None,
        threshold: None,
        refine_budget: 1_000_000,
        return_samples: false,
    }
}

/// A unit square in the plane `z`, split into `2 n²` triangles.
fn square(n: u32, z: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    crate::test_meshes::grid(n, |_, _| z)
}

#[test]
fn parallel_squares_at_distance_d() {
    let (va, fa) = square(4, 0.0);
    let (vb, fb) = square(7, 0.3);
    let tree = TriangleTree::build(&vb, &fb).unwrap();
    for opts in [
        options(),
        Options {
            statistics: false,
            ..options()
        },
    ] {
        let r = directed(&va, &fa, &tree, &opts).unwrap();
        assert!((r.max - 0.3).abs() < 1e-12, "{}", r.max);
        assert!(r.bounds.unwrap().upper >= 0.3 - 1e-12);
        let refined = directed(
            &va,
            &fa,
            &tree,
            &Options {
                tolerance: Some(1e-6),
                ..opts
            },
        )
        .unwrap();
        let b = refined.bounds.unwrap();
        assert_eq!(b.converged, Some(true));
        assert!((b.upper - 0.3).abs() <= 1e-6, "{}", b.upper);
    }
    let s = directed(&va, &fa, &tree, &options())
        .unwrap()
        .statistics
        .unwrap();
    for x in [s.mean, s.rms, s.p50, s.p95, s.p99] {
        assert!((x - 0.3).abs() < 1e-12);
    }
}

/// A flat square (vertices, faces) and the tree of the same square with its centre
/// vertex raised by 0.2 (a cone).
fn flat_and_bump() -> (Vec<[f64; 3]>, Vec<[u32; 3]>, TriangleTree) {
    let (vb, fb) = square(2, 0.0);
    let (mut va, fa) = square(2, 0.0);
    va[4][2] = 0.2;
    (vb, fb, TriangleTree::build(&va, &fa).unwrap())
}

#[test]
fn bump_refines_to_the_tolerance() {
    // h(flat, bump): the flat centre (0.5, 0.5, 0) against the raised cone.
    let (vb, fb, ta) = flat_and_bump();
    let opts = Options {
        area_samples: 50,
        statistics: false,
        tolerance: Some(1e-4),
        ..options()
    };
    let r = directed(&vb, &fb, &ta, &opts).unwrap();
    let b = r.bounds.unwrap();
    assert_eq!(b.converged, Some(true));
    assert!(b.upper - r.max <= 1e-4 + 1e-15, "{} {}", b.upper, r.max);
    let (d, _, _) = ta.query(&[[0.5, 0.5, 0.0]]).unwrap();
    let truth = d[0];
    assert!(
        r.max <= truth + 1e-12 && truth <= b.upper + 1e-12,
        "{} {} {}",
        r.max,
        truth,
        b.upper
    );
}

/// A relative tolerance refines to that fraction of the sampled maximum; on identical
/// meshes (maximum 0) it still ends, at the floor.
#[test]
fn a_relative_tolerance_refines_to_a_fraction_of_the_maximum() {
    let (vb, fb, ta) = flat_and_bump();
    let opts = Options {
        area_samples: 50,
        statistics: false,
        relative_tolerance: Some(0.01),
        ..options()
    };
    let r = directed(&vb, &fb, &ta, &opts).unwrap();
    let b = r.bounds.unwrap();
    assert_eq!(b.converged, Some(true));
    assert!(b.upper - r.max <= 0.01 * r.max, "{} {}", b.upper, r.max);
    assert!(b.refined_points > 0);
    let tb = TriangleTree::build(&vb, &fb).unwrap();
    let same = directed(&vb, &fb, &tb, &opts).unwrap();
    assert_eq!(same.max, 0.0);
    let b = same.bounds.unwrap();
    assert_eq!(b.converged, Some(true));
    assert!(b.upper <= RELATIVE_FLOOR * tb.half_extent(), "{}", b.upper);
    let bad = Options {
        relative_tolerance: Some(-1.0),
        ..opts
    };
    assert!(directed(&vb, &fb, &ta, &bad).is_err());
}

#[test]
fn a_threshold_decides_with_less_refinement() {
    // h(flat, bump) is the distance of the flat centre to the cone, about 0.14.
    let (vb, fb, ta) = flat_and_bump();
    let base = Options {
        area_samples: 50,
        statistics: false,
        tolerance: Some(1e-6),
        ..options()
    };
    let tight = directed(&vb, &fb, &ta, &base).unwrap();
    let truth = tight.max;
    for threshold in [truth * 1.2, truth * 0.8] {
        let r = directed(
            &vb,
            &fb,
            &ta,
            &Options {
                threshold: Some(threshold),
                ..base
            },
        )
        .unwrap();
        let b = r.bounds.unwrap();
        assert_eq!(b.converged, Some(true));
        assert!(r.max <= truth + 1e-12 && truth <= b.upper + 1e-12);
        if threshold > truth {
            assert!(b.upper <= threshold, "{} > {threshold}", b.upper);
        } else {
            assert!(r.max > threshold, "{} <= {threshold}", r.max);
        }
        assert!(
            b.refined_points < tight.bounds.unwrap().refined_points,
            "{} {}",
            b.refined_points,
            tight.bounds.unwrap().refined_points
        );
    }
}

#[test]
fn samples_drawn_once_measure_every_target() {
    let (va, fa) = square(9, 0.0);
    let mut targets = Vec::new();
    for shift in [0.1, 0.7, -0.4] {
        let (mut vb, fb) = square(5, 0.2);
        for (i, p) in vb.iter_mut().enumerate() {
            p[0] += shift;
            p[2] += 0.05 * ((i * 7919) % 13) as f64 / 13.0;
        }
        targets.push(TriangleTree::build(&vb, &fb).unwrap());
    }
    let opts = Options {
        tolerance: Some(1e-4),
        ..options()
    };
    let samples = surface_samples(&va, &fa, DVec3::new(3.0, -1.0, 0.5), 2000, 1).unwrap();
    for tree in &targets {
        let fresh = directed(&va, &fa, tree, &opts).unwrap();
        let reused = directed_from_samples(&va, &fa, &samples, tree, &opts).unwrap();
        assert!(
            (fresh.max - reused.max).abs() <= 1e-14,
            "{} {}",
            fresh.max,
            reused.max
        );
        let (fu, ru) = (fresh.bounds.unwrap().upper, reused.bounds.unwrap().upper);
        assert!((fu - ru).abs() <= 1e-14, "{fu} {ru}");
        assert_eq!(fresh.n_samples, reused.n_samples);
    }
    let other = surface_samples(&va, &fa[1..], DVec3::ZERO, 100, 1).unwrap();
    assert!(directed_from_samples(&va, &fa, &other, &targets[0], &opts).is_err());
}

/// A source collapsed to one point: its cells are points, never split. A reachable
/// tolerance settles them at once; one under the rounding margin ends unconverged
/// without refining (it split copies of the point until the budget ran out).
#[test]
fn cells_of_one_point_are_never_split() {
    let (vb, fb) = square(5, 0.0);
    let tree = TriangleTree::build(&vb, &fb).unwrap();
    let (_, fa) = square(9, 0.0);
    let va = vec![[0.3, 0.4, 0.25]; 100];
    for (tolerance, converged) in [(1e-6, true), (1e-18, false)] {
        let opts = Options {
            tolerance: Some(tolerance),
            ..options()
        };
        let r = directed(&va, &fa, &tree, &opts).unwrap();
        let b = r.bounds.unwrap();
        assert_eq!(b.converged, Some(converged), "tolerance {tolerance}");
        assert_eq!((b.refined_points, b.refined_cells), (0, 0));
        assert!((r.max - 0.25).abs() < 1e-15, "{}", r.max);
        assert!(b.upper >= r.max && b.upper - r.max < 1e-12, "{}", b.upper);
    }
}

#[test]
fn max_only_agrees_with_full_statistics() {
    let (va, fa) = square(9, 0.0);
    let (mut vb, fb) = square(5, 0.0);
    for (i, p) in vb.iter_mut().enumerate() {
        p[2] = 0.05 * ((i * 7919) % 13) as f64 / 13.0;
    }
    let tree = TriangleTree::build(&vb, &fb).unwrap();
    let full = directed(
        &va,
        &fa,
        &tree,
        &Options {
            bounds: false,
            ..options()
        },
    )
    .unwrap();
    let fast = directed(
        &va,
        &fa,
        &tree,
        &Options {
            bounds: false,
            statistics: false,
            ..options()
        },
    )
    .unwrap();
    assert_eq!(full.max, fast.max);
    assert_eq!(full.argmax, fast.argmax);
    assert_eq!(full.argmax_closest, fast.argmax_closest);
    assert!(fast.statistics.is_none());
}

/// The statistics describe the area samples; the vertices, searched max-only, still
/// give the maximum when it lies at one of them (here a spike vertex).
#[test]
fn statistics_are_the_area_samples_and_a_vertex_can_hold_the_maximum() {
    let (mut va, fa) = square(9, 0.0);
    va[37][2] = 0.3;
    let (mut vb, fb) = square(5, 0.0);
    for (i, p) in vb.iter_mut().enumerate() {
        p[2] = 0.05 * ((i * 7919) % 13) as f64 / 13.0;
    }
    let tree = TriangleTree::build(&vb, &fb).unwrap();
    let stats_only = Options {
        bounds: false,
        ..options()
    };
    let with_samples = Options {
        return_samples: true,
        ..stats_only
    };
    let fast = directed(&va, &fa, &tree, &stats_only).unwrap();
    let all = directed(&va, &fa, &tree, &with_samples).unwrap();
    let data = all.samples.as_ref().unwrap();
    let nv = all.n_vertex_samples;
    assert_eq!(nv, va.len());
    let brute: Vec<f64> = data
        .points
        .iter()
        .map(|&p| {
            let q = DVec3::from(p) - tree.centre();
            fb.iter()
                .map(|f| {
                    let [a, b, c] = f.map(|i| DVec3::from(vb[i as usize]) - tree.centre());
                    crate::closest::closest_point_on_triangle(q, a, b, c).1
                })
                .fold(f64::INFINITY, f64::min)
                .sqrt()
        })
        .collect();
    let argmax = (0..brute.len()).fold(0, |b, i| if brute[i] > brute[b] { i } else { b });
    assert!(argmax < nv, "the spike vertex holds the maximum");
    assert_eq!(fast.max, all.max);
    assert_eq!(fast.argmax, data.points[argmax]);
    assert!((fast.max - brute[argmax]).abs() < 1e-12);
    let area: Vec<f64> = data.distances[nv..].to_vec();
    assert_eq!(fast.statistics, Some(statistics(&area)));
    let mean = area.iter().sum::<f64>() / area.len() as f64;
    let got = fast.statistics.unwrap();
    assert!((got.mean - mean).abs() < 1e-12);
    let with_vertices = data.distances.iter().sum::<f64>() / data.distances.len() as f64;
    assert!(
        (got.mean - with_vertices).abs() > 1e-6,
        "the vertices are left out"
    );
}
