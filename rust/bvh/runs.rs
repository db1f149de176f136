//! Collinear runs: zero-area triangles lying on one line and connected through shared
//! vertices, stored as one leaf and searched as one segment (see *Collinear runs* in the
//! [module docs](super)).
//!
//! A *segment face* has its three recentred corners within `w = RUN_WIDTH · h` of the
//! line through its two farthest corners (`h` the larger of the tree's half extent and
//! the largest coordinate of its centre, length: the input's own rounding grows with
//! both) and those two apart. Segment faces sharing a vertex index form a component; a component of at
//! least [`RUN_MIN_FACES`] faces whose every corner lies within `w` of the line through
//! its two extreme corners `P₁`, `P₂` (`P₁` the corner farthest from the component's
//! first corner, `P₂` the one farthest from `P₁`) is a run. Its faces' segments overlap
//! along `U = [P₁, P₂]`: shared vertices chain them, so their union covers `U`.
//!
//! **Search.** Along `U`, a point `P₁ + s (P₂ - P₁)` has the parameter `s ∈ [0, 1]`
//! (dimensionless); a corner `x` has `s(x) = (x - P₁)·(P₂ - P₁) / |P₂ - P₁|²`, clamped,
//! and a face the interval of its corners' parameters. For a query `p`, the parameter
//! `s_p` of its closest point on `U` is computed the same way; the run answers the
//! smallest face whose interval holds `s_p` (a table over the sorted interval ends,
//! binary-searched) and that face's own exact distance. Every face of the run is within
//! `w` of `U`, so that distance exceeds the smallest over the run's faces by at most
//! about `2w` (plus rounding), and it is the distance to a point of the mesh. Without
//! runs, a bunny collapsed onto a diagonal (69,451 faces, every point of the line inside
//! about 450 segments, each box far looser than its segment) tested 5,600 triangles per
//! query; its one run tests one.

use glam::DVec3;
use obvhs::aabb::Aabb;
use rayon::prelude::*;

/// Width of a run relative to the mesh's scale (`2⁻⁴⁶`, dimensionless; see the
/// [module docs](self)): corners this close to a line count as on it, 64 ulps of the
/// coordinates.
pub(super) const RUN_WIDTH: f64 = 1.0 / (1u64 << 46) as f64;

/// Fewest faces of a run: smaller components gain nothing and stay triangles.
pub(super) const RUN_MIN_FACES: usize = 8;

/// A run as the tree stores it: its slots, its segment `U` and the table of its faces
/// along it (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Run {
    /// First slot; the run's faces are slots `first .. first + len`, in face order.
    pub(super) first: u32,
    pub(super) len: u32,
    /// `P₁` (recentred frame, length).
    start: DVec3,
    /// `P₂ - P₁` (length) and its squared length (length², positive).
    dir: DVec3,
    dir2: f64,
    /// Sorted distinct parameters of the faces' interval ends, from 0 to 1
    /// (dimensionless).
    breaks: Vec<f64>,
    /// Per piece of `[0, 1]` (`2k`: the parameter `breaks[k]`; `2k + 1`: the open
    /// interval between `breaks[k]` and `breaks[k + 1]`), the run-local index (slot -
    /// `first`) of the smallest face whose interval holds it.
    pieces: Vec<u32>,
}

impl Run {
    /// The slot of the smallest face of the run whose interval holds the parameter of
    /// `p`'s closest point on `U` (recentred frame).
    #[inline]
    pub(super) fn slot_for(&self, p: DVec3) -> u32 {
        let s = ((p - self.start).dot(self.dir) / self.dir2).clamp(0.0, 1.0);
        // NaN (not for finite queries) goes to the first piece.
        let s = if s.is_nan() { 0.0 } else { s };
        let k = self.breaks.partition_point(|&b| b < s);
        let piece = match self.breaks.get(k) {
            Some(&b) if b == s => 2 * k,
            _ => (2 * k).saturating_sub(1),
        };
        let piece = piece.min(self.pieces.len() - 1);
        self.first + self.pieces[piece]
    }

    /// Its slots are `first .. first + len`, its table names them only, every piece is
    /// named, and the parameters are sorted from 0 to 1.
    pub(super) fn check(&self) -> Result<(), String> {
        let sorted = self.breaks.windows(2).all(|w| w[0] < w[1]);
        if self.breaks.first() != Some(&0.0) || self.breaks.last() != Some(&1.0) || !sorted {
            return Err(format!("run at slot {}: parameters not 0 .. 1", self.first));
        }
        if self.pieces.len() != 2 * self.breaks.len() - 1
            || self.pieces.iter().any(|&i| i >= self.len)
            || self.dir2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        {
            return Err(format!("run at slot {}: bad table", self.first));
        }
        Ok(())
    }
}

/// A run found before the build: its faces (increasing) and box; placed in the tree
/// as [`Run`] once its first slot is known.
#[derive(Debug)]
pub(super) struct FoundRun {
    pub(super) faces: Vec<u32>,
    /// Union of the faces' boxes.
    pub(super) aabb: Aabb,
    start: DVec3,
    dir: DVec3,
    dir2: f64,
    breaks: Vec<f64>,
    pieces: Vec<u32>,
}

impl FoundRun {
    /// The run as stored from slot `first` on.
    pub(super) fn placed(&self, first: u32) -> Run {
        Run {
            first,
            len: self.faces.len() as u32,
            start: self.start,
            dir: self.dir,
            dir2: self.dir2,
            breaks: self.breaks.clone(),
            pieces: self.pieces.clone(),
        }
    }
}

/// Whether the corners are a segment face: the two farthest apart differ, and the third
/// lies within `w` (length) of their line.
fn is_segment(c: [DVec3; 3], w: f64) -> bool {
    let edges = [(0, 1, 2), (1, 2, 0), (2, 0, 1)];
    let (i, j, k) = edges
        .into_iter()
        .max_by(|a, b| {
            let la = (c[a.1] - c[a.0]).length_squared();
            let lb = (c[b.1] - c[b.0]).length_squared();
            la.total_cmp(&lb)
        })
        .unwrap_or((0, 1, 2));
    let d = c[j] - c[i];
    let l2 = d.length_squared();
    l2 > 0.0 && off_line2(c[k] - c[i], d, l2) <= w * w
}

/// Squared distance (length²) of `x` (relative to a point of the line) from the line of
/// direction `d`, `l2 = |d|² > 0`.
#[inline]
fn off_line2(x: DVec3, d: DVec3, l2: f64) -> f64 {
    x.cross(d).length_squared() / l2
}

/// Root of `i` in the union-find `parent`, halving paths.
fn root(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let up = parent[parent[i as usize] as usize];
        parent[i as usize] = up;
        i = up;
    }
    i
}

/// The runs of the mesh (`local`: recentred corner of a vertex index; `boxes`: the
/// faces' boxes; `scale`: `h` of the [module docs](self), length), in the order of their
/// smallest face.
/// Empty for most meshes, after one pass over the faces.
pub(super) fn find_runs(
    faces: &[[u32; 3]],
    vertex_count: usize,
    local: impl Fn(u32) -> DVec3 + Sync,
    boxes: &[Aabb],
    scale: f64,
) -> Vec<FoundRun> {
    let w = RUN_WIDTH * scale;
    let corners = |f: &[u32; 3]| f.map(&local);
    let segments: Vec<u32> = (0..faces.len() as u32)
        .into_par_iter()
        .filter(|&f| is_segment(corners(&faces[f as usize]), w))
        .collect();
    if segments.len() < RUN_MIN_FACES {
        return Vec::new();
    }
    // Components through shared vertex indices, in the order of their smallest face.
    let mut parent: Vec<u32> = (0..vertex_count as u32).collect();
    for &f in &segments {
        let [a, b, c] = faces[f as usize];
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        parent[rb as usize] = ra;
        let rc = root(&mut parent, c);
        parent[rc as usize] = ra;
    }
    let mut keyed: Vec<(u32, u32)> = segments
        .iter()
        .map(|&f| (root(&mut parent, faces[f as usize][0]), f))
        .collect();
    keyed.sort_unstable();
    let mut components: Vec<Vec<u32>> = keyed
        .chunk_by(|a, b| a.0 == b.0)
        .filter(|c| c.len() >= RUN_MIN_FACES)
        .map(|c| c.iter().map(|&(_, f)| f).collect())
        .collect();
    components.sort_unstable_by_key(|c| c[0]);
    components
        .into_par_iter()
        .filter_map(|c| run_of(&c, faces, &local, boxes, w))
        .collect()
}

/// The component `faces_in` (increasing) as a run, if its corners lie within `w`
/// (length) of one line and its table covers `[0, 1]`.
fn run_of(
    faces_in: &[u32],
    faces: &[[u32; 3]],
    local: &(impl Fn(u32) -> DVec3 + Sync),
    boxes: &[Aabb],
    w: f64,
) -> Option<FoundRun> {
    let corners = || faces_in.iter().flat_map(|&f| faces[f as usize].map(local));
    let farthest = |from: DVec3| {
        corners().fold((from, 0.0_f64), |(best, d2), x| {
            let e = (x - from).length_squared();
            if e > d2 { (x, e) } else { (best, d2) }
        })
    };
    let first = corners().next()?;
    let (start, _) = farthest(first);
    let (end, dir2) = farthest(start);
    let dir = end - start;
    if dir2 <= 0.0
        || !dir2.is_finite()
        || corners().any(|x| off_line2(x - start, dir, dir2) > w * w)
    {
        return None;
    }
    let param = |x: DVec3| ((x - start).dot(dir) / dir2).clamp(0.0, 1.0);
    let intervals: Vec<(f64, f64)> = faces_in
        .iter()
        .map(|&f| {
            let s = faces[f as usize].map(|v| param(local(v)));
            (s[0].min(s[1]).min(s[2]), s[0].max(s[1]).max(s[2]))
        })
        .collect();
    let mut breaks: Vec<f64> = intervals.iter().flat_map(|&(a, b)| [a, b]).collect();
    breaks.sort_unstable_by(f64::total_cmp);
    breaks.dedup();
    if breaks.first() != Some(&0.0) || breaks.last() != Some(&1.0) {
        return None;
    }
    let pieces = paint(&breaks, &intervals)?;
    let aabb = faces_in
        .iter()
        .fold(Aabb::INVALID, |a, &f| a.union(&boxes[f as usize]));
    Some(FoundRun {
        faces: faces_in.to_vec(),
        aabb,
        start,
        dir,
        dir2,
        breaks,
        pieces,
    })
}

/// Per piece of `breaks` (see [`Run`]), the first of `intervals` holding it; None when a
/// piece is held by none. Each interval paints the pieces no earlier one painted (a
/// pointer to the next unpainted piece, halved as it is followed).
fn paint(breaks: &[f64], intervals: &[(f64, f64)]) -> Option<Vec<u32>> {
    let n = 2 * breaks.len() - 1;
    let mut pieces = vec![u32::MAX; n];
    // next[i]: the first piece at or after i that may be unpainted (n: none).
    let mut next: Vec<u32> = (0..=n as u32).collect();
    let find = |next: &mut Vec<u32>, mut i: u32| {
        while next[i as usize] != i {
            let up = next[next[i as usize] as usize];
            next[i as usize] = up;
            i = up;
        }
        i
    };
    let at = |s: f64| breaks.partition_point(|&b| b < s);
    for (index, &(lo, hi)) in intervals.iter().enumerate() {
        let (a, b) = (2 * at(lo), 2 * at(hi));
        let mut i = find(&mut next, a as u32);
        while (i as usize) <= b && (i as usize) < n {
            pieces[i as usize] = index as u32;
            next[i as usize] = i + 1;
            i = find(&mut next, i + 1);
        }
    }
    (!pieces.contains(&u32::MAX)).then_some(pieces)
}
