//! The tree's tests: every size from 1 to 100 validated and matched against brute force,
//! hints, early exits, ties, collapsed meshes (with bounds on the work per query), meshes
//! collapsed onto a line, far from the origin.

use glam::DVec3;

use super::TriangleTree;
use super::runs::RUN_WIDTH;
use super::search::counters::counted;
use super::tree::{IDENTICAL, RUN};
use crate::closest::closest_point_on_triangle;

fn lcg(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*state >> 11) as f64) / ((1u64 << 53) as f64)
}

/// A random soup of `n` small triangles in the unit cube, some degenerate.
fn soup(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut s = seed;
    let mut v = Vec::new();
    let mut f = Vec::new();
    for i in 0..n {
        let c = [lcg(&mut s), lcg(&mut s), lcg(&mut s)];
        let base = v.len() as u32;
        for _ in 0..3 {
            v.push([
                c[0] + 0.1 * lcg(&mut s),
                c[1] + 0.1 * lcg(&mut s),
                c[2] + 0.1 * lcg(&mut s),
            ]);
        }
        match i % 7 {
            0 => f.push([base, base, base + 1]),
            1 => {
                let (a, b) = (v[base as usize], v[base as usize + 1]);
                v[base as usize + 2] = [
                    (a[0] + b[0]) / 2.0,
                    (a[1] + b[1]) / 2.0,
                    (a[2] + b[2]) / 2.0,
                ];
                f.push([base, base + 1, base + 2]);
            }
            _ => f.push([base, base + 1, base + 2]),
        }
    }
    (v, f)
}

fn brute(v: &[[f64; 3]], f: &[[u32; 3]], p: DVec3) -> (f64, u32) {
    let at = |i: u32| DVec3::from_array(v[i as usize]);
    f.iter()
        .enumerate()
        .map(|(i, t)| {
            (
                closest_point_on_triangle(p, at(t[0]), at(t[1]), at(t[2])).1,
                i as u32,
            )
        })
        .fold(
            (f64::INFINITY, u32::MAX),
            |a, b| if b.0 < a.0 { b } else { a },
        )
}

#[test]
fn every_size_from_1_to_100_validates_and_matches_brute_force() {
    for n in 1..=100 {
        let (v, f) = soup(n, n as u64);
        let tree = TriangleTree::build(&v, &f).unwrap();
        tree.validate().unwrap_or_else(|e| panic!("n = {n}: {e}"));
        assert_eq!(tree.len(), n);
        assert_matches_brute_force(&tree, &v, &f, 99 + n as u64, 20);
    }
}

/// Nearest distances of `queries` seeded points around the unit cube equal brute
/// force's (the same triangles, recentred: equal up to rounding).
fn assert_matches_brute_force(
    tree: &TriangleTree,
    v: &[[f64; 3]],
    f: &[[u32; 3]],
    seed: u64,
    queries: usize,
) {
    let mut s = seed;
    let mut stack = tree.stack();
    for _ in 0..queries {
        let p = DVec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 1.4 - 0.2;
        let hit = tree
            .nearest_local(p - tree.centre(), u32::MAX, 0.0, &mut stack)
            .unwrap();
        let (d2, _) = brute(v, f, p);
        assert!(
            (hit.d2.sqrt() - d2.sqrt()).abs() < 1e-14,
            "{} faces: {} vs {d2}",
            f.len(),
            hit.d2
        );
    }
}

#[test]
fn a_deep_tree_validates_matches_brute_force_and_does_not_depend_on_threads() {
    let (v, f) = soup(20_000, 7);
    let tree = TriangleTree::build(&v, &f).unwrap();
    tree.validate().unwrap();
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| TriangleTree::build(&v, &f).unwrap());
    assert_eq!(single.faces, tree.faces);
    assert_eq!(single.depth, tree.depth);
    assert_matches_brute_force(&tree, &v, &f, 5, 50);
}

#[test]
fn hints_and_early_exit() {
    let (v, f) = soup(500, 3);
    let tree = TriangleTree::build(&v, &f).unwrap();
    let mut stack = tree.stack();
    let p = DVec3::new(0.5, 0.5, 0.5) - tree.centre();
    let exact = tree.nearest_local(p, u32::MAX, 0.0, &mut stack).unwrap();
    for hint in [0, 17, 499] {
        assert_eq!(tree.nearest_local(p, hint, 0.0, &mut stack).unwrap(), exact);
    }
    // Stopping below a huge threshold returns the hint itself.
    let early = tree
        .nearest_local(p, 17, f64::INFINITY, &mut stack)
        .unwrap();
    assert_eq!(early.slot, 17);
    assert!(early.d2 >= exact.d2);
}

/// An exact search started from any hint (near the query or across the tree) climbs
/// from the hint's subtree to the root and returns the brute-force nearest triangle.
#[test]
fn exact_search_from_any_hint_matches_brute_force() {
    let (v, f) = soup(20_000, 5);
    let tree = TriangleTree::build(&v, &f).unwrap();
    let mut stack = tree.stack();
    let mut state = 99u64;
    for _ in 0..300 {
        let p =
            DVec3::new(lcg(&mut state), lcg(&mut state), lcg(&mut state)) * 1.4 - DVec3::splat(0.2);
        let (d2, face) = brute(&v, &f, p);
        let unhinted = tree
            .nearest_local(p - tree.centre(), u32::MAX, 0.0, &mut stack)
            .unwrap();
        for hint in [
            unhinted.slot,
            (lcg(&mut state) * 20_000.0) as u32,
            0,
            19_999,
        ] {
            let hit = tree
                .nearest_local(p - tree.centre(), hint, 0.0, &mut stack)
                .unwrap();
            assert_eq!(hit, unhinted, "hint {hint}");
            assert_eq!(hit.face, face);
            assert!((hit.d2.sqrt() - d2.sqrt()).abs() < 1e-14);
        }
    }
}

/// An early-exit search along a path of nearby queries, each hinted by the previous
/// answer (so that it starts in the hint's subtree): below the stop distance it returns
/// a triangle within it, at its true distance; otherwise the exact nearest.
#[test]
fn early_exit_from_the_hints_subtree_matches_brute_force() {
    let (v, f) = soup(20_000, 11);
    let tree = TriangleTree::build(&v, &f).unwrap();
    let mut stack = tree.stack();
    let mut hint = u32::MAX;
    let (mut early, mut exact_answers) = (0, 0);
    for step in 0..2_000 {
        let t = step as f64 / 2_000.0;
        let p = DVec3::new(t, 0.5 + 0.3 * (7.0 * t).sin(), 0.5 + 0.3 * (5.0 * t).cos());
        let (exact, _) = brute(&v, &f, p);
        let stop = 0.01 * 0.01;
        let hit = tree
            .nearest_local(p - tree.centre(), hint, stop, &mut stack)
            .unwrap();
        let face = f[hit.face as usize];
        let at = |i: u32| DVec3::from_array(v[i as usize]);
        let (_, true_d2) = closest_point_on_triangle(p, at(face[0]), at(face[1]), at(face[2]));
        assert!((hit.d2 - true_d2).abs() <= 1e-12 * (1.0 + true_d2));
        if exact < stop {
            assert!(hit.d2 < stop, "step {step}: {} not below the stop", hit.d2);
            early += 1;
        } else {
            assert!((hit.d2.sqrt() - exact.sqrt()).abs() < 1e-14, "step {step}");
            exact_answers += 1;
        }
        hint = hit.slot;
    }
    assert!(
        early > 100 && exact_answers > 100,
        "{early} early, {exact_answers} exact"
    );
}

/// The overlap measured on the tree's f32 boxes is the f64 one of `reduce`, up to the
/// boxes' outward rounding.
#[test]
fn box_overlap_matches_the_f64_pass() {
    for (n, seed) in [(1, 1), (37, 2), (5_000, 3)] {
        let (v, f) = soup(n, seed);
        let tree = TriangleTree::build(&v, &f).unwrap();
        let exact = crate::reduce::box_overlap(&v, &f);
        assert!(exact > 0.0);
        let rel = (tree.box_overlap() - exact).abs() / exact;
        assert!(rel < 1e-5, "{n} faces: {} vs {exact}", tree.box_overlap());
    }
    assert_eq!(
        TriangleTree::build(&[[0.0; 3]], &[]).unwrap().box_overlap(),
        0.0
    );
}

/// `farther_than` agrees with the exact distances of `query`, at several distances.
#[test]
fn farther_than_matches_the_exact_distances() {
    let (v, f) = soup(3_000, 21);
    let tree = TriangleTree::build(&v, &f).unwrap();
    let mut s = 5;
    let points: Vec<[f64; 3]> = (0..4_000)
        .map(|_| [lcg(&mut s), lcg(&mut s), lcg(&mut s)].map(|x| x * 1.4 - 0.2))
        .collect();
    let (exact, _, _) = tree.query(&points).unwrap();
    for distance in [0.0, 0.01, 0.05, 0.2, 10.0] {
        let far = tree.farther_than(&points, distance).unwrap();
        for (i, (&d, &verdict)) in exact.iter().zip(&far).enumerate() {
            assert_eq!(verdict, d > distance, "point {i}: {d} against {distance}");
        }
    }
    assert!(tree.farther_than(&points, -1.0).is_err());
    assert!(tree.farther_than(&[[f64::NAN, 0.0, 0.0]], 0.1).is_err());
}

#[test]
fn empty_tree_and_leaf_root() {
    let tree = TriangleTree::build(&[[0.0; 3]], &[]).unwrap();
    tree.validate().unwrap();
    assert!(
        tree.nearest_local(DVec3::ZERO, u32::MAX, 0.0, &mut tree.stack())
            .is_none()
    );
    assert!(tree.query(&[[0.0; 3]]).is_err());
    let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let tree = TriangleTree::build(&v, &[[0, 1, 2]]).unwrap();
    tree.validate().unwrap();
    let (d, q, face) = tree.query(&[[0.25, 0.25, 2.0]]).unwrap();
    assert_eq!((d[0], face[0]), (2.0, 0));
    assert_eq!(q[0], [0.25, 0.25, 0.0]);
}

#[test]
fn ties_go_to_the_smallest_face_index() {
    // The same triangle four times, in a larger mesh.
    let (mut v, mut f) = soup(50, 5);
    let base = v.len() as u32;
    v.extend([[2.0, 2.0, 2.0], [3.0, 2.0, 2.0], [2.0, 3.0, 2.0]]);
    for _ in 0..4 {
        f.push([base, base + 1, base + 2]);
    }
    let tree = TriangleTree::build(&v, &f).unwrap();
    let (_, _, face) = tree.query(&[[2.2, 2.2, 2.5]]).unwrap();
    assert_eq!(face[0], 50);
}

/// `n` faces of the soup with every vertex at one point (a mesh collapsed by a coarse
/// quantization), some faces repeated with permuted corners.
fn collapsed(n: usize, at: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (v, mut f) = soup(n, 4);
    for (i, face) in f.iter_mut().enumerate() {
        face.rotate_left(i % 3);
    }
    (vec![at; v.len()], f)
}

/// Queries around the unit cube against `tree`: each answer is brute force's (the
/// smallest face at the smallest distance, whatever the hint), and the triangles
/// tested and pairs visited per query average at most `tested` and `pairs`.
fn assert_bounded_and_exact(
    tree: &TriangleTree,
    v: &[[f64; 3]],
    f: &[[u32; 3]],
    tested: f64,
    pairs: f64,
) {
    tree.validate().unwrap();
    let mut stack = tree.stack();
    let mut s = 17;
    let mut hint = u32::MAX;
    let (mut all_tested, mut all_pairs, queries) = (0, 0, 400);
    for i in 0..queries {
        let p = DVec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 1.4 - 0.2;
        let (hit, t, q) = counted(|| tree.nearest_local(p - tree.centre(), hint, 0.0, &mut stack));
        let hit = hit.unwrap();
        (all_tested, all_pairs) = (all_tested + t, all_pairs + q);
        let (d2, _) = brute(v, f, p);
        assert!(
            (hit.d2.sqrt() - d2.sqrt()).abs() < 1e-14,
            "{} vs {d2}",
            hit.d2
        );
        // Exactly the smallest (d², face) over every stored triangle (the tree's frame).
        let exact = (0..tree.len() as u32)
            .map(|slot| {
                let d2 = tree.triangle(slot).closest(p - tree.centre()).1;
                (d2, tree.faces[slot as usize])
            })
            .fold((f64::INFINITY, u32::MAX), |a, b| if b < a { b } else { a });
        assert_eq!((hit.d2, hit.face), exact, "query {i}");
        let unhinted = tree.nearest_local(p - tree.centre(), u32::MAX, 0.0, &mut stack);
        assert_eq!(unhinted, Some(hit));
        // Every hint, including a slot that is not the first of identical triangles.
        hint = (lcg(&mut s) * f.len() as f64) as u32;
    }
    let (t, q) = (
        all_tested as f64 / f64::from(queries),
        all_pairs as f64 / f64::from(queries),
    );
    assert!(
        t <= tested && q <= pairs,
        "{t} triangles, {q} pairs per query"
    );
}

/// A mesh collapsed to one point is one leaf of identical triangles: a query tests the
/// hint and the smallest face, and answers that face; the distances are brute force's.
#[test]
fn a_collapsed_mesh_is_one_leaf_tested_once() {
    for at in [[0.0; 3], [0.3, -0.7, 1e3]] {
        let (v, f) = collapsed(20_000, at);
        let tree = TriangleTree::build(&v, &f).unwrap();
        assert_eq!(tree.root_count, 20_000 | IDENTICAL);
        assert_eq!(tree.depth(), 1);
        assert_bounded_and_exact(&tree, &v, &f, 2.0, 0.0);
        let (d, q, face) = tree.query(&[[0.0, 0.0, 5.0], at]).unwrap();
        assert_eq!(face, [0, 0]);
        assert_eq!(q, [at, at]);
        assert_eq!(d[1], 0.0);
    }
}

/// Without merging identical triangles, the tie rule alone (a box at exactly the best
/// distance is skipped unless it holds a smaller face) bounds the search on a mesh
/// collapsed to the centre, where every box is at the best distance: a few paths
/// down the tree, not the 20,000 triangles.
#[test]
fn ties_skip_boxes_without_a_smaller_face() {
    let (v, f) = collapsed(20_000, [0.0; 3]);
    let tree = TriangleTree::build_with(&v, &f, false).unwrap();
    assert_eq!(tree.root_count, 0);
    // One box holding 20,000 faces in a balanced tree (PLOC made a chain 20,000 deep).
    assert_eq!(tree.depth(), 16);
    // 5.8 triangles and 44 pairs per query (visiting every box at the best distance
    // tested the 20,000 triangles).
    assert_bounded_and_exact(&tree, &v, &f, 12.0, 80.0);
}

/// Half the faces collapsed to one point off the centre (padded boxes: the tie rule
/// does not prune them, merging does), the others a soup: exact, and bounded.
#[test]
fn a_partly_collapsed_mesh_is_exact_and_bounded() {
    let (mut v, f) = soup(20_000, 9);
    let at = [0.61, 0.27, 0.43];
    for face in f.iter().step_by(2) {
        for &i in face {
            v[i as usize] = at;
        }
    }
    let tree = TriangleTree::build(&v, &f).unwrap();
    // 13 triangles and 82 pairs per query.
    assert_bounded_and_exact(&tree, &v, &f, 30.0, 160.0);
    // Repeated faces (the same indices) merge too: 7.8 triangles, 45 pairs per query.
    let (v, f) = soup(2_000, 3);
    let f: Vec<[u32; 3]> = f.iter().flat_map(|&t| [t; 7]).collect();
    let tree = TriangleTree::build(&v, &f).unwrap();
    assert_bounded_and_exact(&tree, &v, &f, 16.0, 90.0);
    // 200 distinct triangles closer together than the f32 boxes resolve, each
    // repeated: boxes holding several sets of identical triangles. The boxes cannot
    // tell the 200 apart: a query nearest to them tests each (the copies once).
    let (mut v, f) = soup(4_000, 5);
    let mut s = 3;
    for p in &mut v[..600] {
        *p = [0.61, 0.27, 0.43].map(|x| x + 1e-11 * lcg(&mut s));
    }
    let f: Vec<[u32; 3]> = f.iter().flat_map(|&t| [t; 3]).collect();
    let tree = TriangleTree::build(&v, &f).unwrap();
    let shared = (0..tree.pairs.len()).any(|i| {
        let pair = &tree.pairs[i];
        pair.min[0] == pair.min[1] && pair.max[0] == pair.max[1]
    });
    assert!(shared, "no box holds several sets");
    // 25 triangles, 74 pairs per query.
    assert_bounded_and_exact(&tree, &v, &f, 60.0, 160.0);
}

/// A grid of `2 n²` faces collapsed onto the line `origin + t dir`: the vertex `(x, y)` of
/// the unit square goes to `t = x + 0.37 y`. Every face is a segment, and about `n / 2`
/// of them overlap at each point of the line (a bunny on a diagonal: about 450).
fn on_a_line(n: u32, origin: [f64; 3], dir: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (v, f) = crate::test_meshes::grid(n, |_, _| 0.0);
    let v = v
        .iter()
        .map(|p| {
            let t = p[0] + 0.37 * p[1];
            [0, 1, 2].map(|k| origin[k] + t * dir[k])
        })
        .collect();
    (v, f)
}

/// Queries around the unit cube (scaled by `size`) against a tree holding runs: the
/// distance is the smallest over the stored triangles (brute force, the tree's frame)
/// within `1e-14 size + 4 w` (`w` a run's width; a run answers the smallest face
/// holding the foot of the query on its line, at that face's own exact distance, which
/// the tree reports); the same answer from any hint or none; triangles tested and pairs
/// visited per query average at most `tested` and `pairs`.
fn assert_runs_bounded_and_close(
    tree: &TriangleTree,
    f: &[[u32; 3]],
    size: f64,
    tested: f64,
    pairs: f64,
) {
    tree.validate().unwrap();
    let mut stack = tree.stack();
    let mut s = 23;
    let mut hint = u32::MAX;
    let (mut all_tested, mut all_pairs, queries) = (0, 0, 300);
    let centre = tree.centre();
    for i in 0..queries {
        let p = (DVec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 1.4 - 0.2) * size + centre;
        let (hit, t, q) = counted(|| tree.nearest_local(p - centre, hint, 0.0, &mut stack));
        let hit = hit.unwrap();
        (all_tested, all_pairs) = (all_tested + t, all_pairs + q);
        let d2 = (0..tree.len() as u32)
            .map(|slot| tree.triangle(slot).closest(p - centre).1)
            .fold(f64::INFINITY, f64::min);
        let w = RUN_WIDTH * tree.half_extent().max(centre.abs().max_element());
        assert!(
            (hit.d2.sqrt() - d2.sqrt()).abs() < 1e-14 * size + 4.0 * w,
            "query {i}: {} vs {}",
            hit.d2.sqrt(),
            d2.sqrt()
        );
        let own = tree.triangle(hit.slot).closest(p - centre);
        assert_eq!((own.1, tree.faces[hit.slot as usize]), (hit.d2, hit.face));
        let unhinted = tree.nearest_local(p - centre, u32::MAX, 0.0, &mut stack);
        assert_eq!(unhinted, Some(hit), "query {i}");
        hint = (lcg(&mut s) * f.len() as f64) as u32;
    }
    let (t, q) = (
        all_tested as f64 / f64::from(queries),
        all_pairs as f64 / f64::from(queries),
    );
    assert!(
        t <= tested && q <= pairs,
        "{t} triangles, {q} pairs per query"
    );
}

/// A mesh collapsed onto a line is one run, one leaf: a query tests the hint and the
/// run's face, and answers as brute force does within rounding, on a diagonal, on a line
/// in no special direction, far from the origin, and small. Without runs, the boxes of
/// 45,000 overlapping segments, each far looser than its segment, made a query test
/// 2,400 triangles and visit 2,500 pairs on the diagonal, 6,100 and 6,100 on the second
/// line.
#[test]
fn a_mesh_collapsed_onto_a_line_is_one_run() {
    for (origin, dir, size) in [
        ([0.0; 3], [1.0, 1.0, 1.0], 1.0),
        ([0.1, -0.2, 0.05], [0.3, -0.7, 0.2], 1.0),
        ([1e4, 2e4, -3e4], [1.0, 2.0, 0.3], 1.0),
        ([0.0; 3], [1e-3, 1e-3, 1e-3], 1e-3),
    ] {
        let (v, f) = on_a_line(150, origin, dir);
        let tree = TriangleTree::build(&v, &f).unwrap();
        assert_eq!(tree.runs.len(), 1, "{dir:?}");
        assert_eq!(tree.root_count, f.len() as u32 | RUN, "{dir:?}");
        assert_runs_bounded_and_close(&tree, &f, size, 2.0, 0.0);
    }
}

/// Half the faces collapsed onto a line, the others a soup around it; and ten lines
/// (a grid's rows, each collapsed onto its own line in a plane): runs beside triangles,
/// close to brute force, and bounded.
#[test]
fn runs_beside_triangles_are_close_and_bounded() {
    let (mut v, mut f) = on_a_line(100, [0.0; 3], [1.0, 1.0, 1.0]);
    let (sv, sf) = soup(20_000, 11);
    let base = v.len() as u32;
    v.extend(sv);
    f.extend(sf.iter().map(|t| t.map(|i| i + base)));
    let tree = TriangleTree::build(&v, &f).unwrap();
    assert_eq!(tree.runs.len(), 1);
    // 11 triangles and 67 pairs per query.
    assert_runs_bounded_and_close(&tree, &f, 1.0, 25.0, 140.0);
    // Rows of a grid in the plane z = x, each row's faces on the diagonal of its own:
    // the faces between rows are triangles.
    let (v, f) = crate::test_meshes::grid(200, |_, _| 0.0);
    let v: Vec<[f64; 3]> = v
        .iter()
        .map(|p| {
            let row = (p[1] * 10.0).round() / 10.0;
            [p[0] + 0.1 * p[1], row, p[0] + 0.1 * p[1]]
        })
        .collect();
    let tree = TriangleTree::build(&v, &f).unwrap();
    assert_eq!(tree.runs.len(), 11);
    // 29 triangles and 62 pairs per query.
    assert_runs_bounded_and_close(&tree, &f, 1.0, 60.0, 130.0);
}

#[test]
fn far_from_the_origin() {
    let (v, f) = soup(200, 8);
    let shifted: Vec<[f64; 3]> = v.iter().map(|p| p.map(|x| x + 1e6)).collect();
    let (t0, t1) = (
        TriangleTree::build(&v, &f).unwrap(),
        TriangleTree::build(&shifted, &f).unwrap(),
    );
    t1.validate().unwrap();
    let pts: Vec<[f64; 3]> = (0..50).map(|i| [0.01 * i as f64, 0.5, 0.3]).collect();
    let pts_shifted: Vec<[f64; 3]> = pts.iter().map(|p| p.map(|x| x + 1e6)).collect();
    let (d0, _, f0) = t0.query(&pts).unwrap();
    let (d1, _, f1) = t1.query(&pts_shifted).unwrap();
    assert_eq!(f0, f1);
    for (a, b) in d0.iter().zip(&d1) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }
}

#[test]
fn non_finite_points_are_refused() {
    let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let tree = TriangleTree::build(&v, &[[0, 1, 2]]).unwrap();
    assert!(tree.query(&[[f64::NAN, 0.0, 0.0]]).is_err());
    assert!(TriangleTree::build(&[[f64::INFINITY, 0.0, 0.0]], &[[0, 0, 0]]).is_err());
    assert!(TriangleTree::build(&v, &[[0, 1, 3]]).is_err());
}
