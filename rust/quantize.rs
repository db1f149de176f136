//! Grid quantization to `B` bits per coordinate and vertex clustering (King & Rossignac
//! 1999, Sec. 1.1 and 3.3; Rossignac & Borrel's clustering, the paper's reference [20]).
//!
//! **Grid.** A box `[min, max]` (by default the vertices' bounding box) and `N = 2^B - 1`
//! steps per axis. `grid = cube` (the paper, Draco, gltfpack): one step
//! `s = S / N` on every axis, with `S` the largest box side; `grid = axes`: a step
//! `s_a = (max_a - min_a) / N` per axis. All arithmetic is in f64, relative to `min`,
//! so 32-bit codes and coordinates far from the origin keep their precision.
//!
//! **Codes** (corner convention, paper Sec. 1.1): per axis
//! `q = round((x - min) / s)` in `[0, N]`, rounding halves up (the argument is never
//! negative), with `s` the f64 value of `S / N`. The dequantised position is
//! `x' = min + q * s`. The centred convention of Sec. 8 (codes in
//! `[-2^(B-1) + 1, 2^(B-1)]`) is the same grid with codes shifted by
//! [`Grid::centered_offset`]: positions, bound and clustering do not change.
//!
//! **Bound.** Each coordinate moves by at most `s_a / 2`, so a point moves by at most
//! `|s| / 2` (`(sqrt(3) / 2) * s` for the cube grid), plus the f64 rounding of the
//! position (a few ulp of the largest coordinate).
//!
//! **Zero extent.** An axis whose step is 0 (a flat axis under `axes`, or every axis when
//! all points coincide) gets code 0 and keeps `x' = min` exactly: the points have no
//! extent there to lose. A positive side whose step would underflow below the smallest
//! normal f64 is refused.
//!
//! **Clustering.** Vertices with equal codes merge into one vertex at the dequantised
//! position of their code. A face with two equal corners after merging is dropped
//! (degenerate); optionally a face repeating an earlier kept face is dropped (duplicate,
//! see [`Duplicates`]). Vertices that no kept face uses are dropped (unreferenced).
//! Output order, independent of the thread count: new vertices in order of the smallest
//! input index of their cluster; kept faces in input order.
//!
//! Vertices are grouped by their packed codes: for `B <= 21` by partitioning on a hash
//! and small per-partition hash tables, above by a stable LSD radix sort; either way the
//! groups are numbered by their smallest vertex index.

use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::error::{MeshError, VertexIndex, check_finite, check_indices};

/// Largest supported bits per coordinate: codes are `u32`.
pub const MAX_BITS: u32 = 32;

/// Digit width of the LSD radix sort of codes, in bits.
const RADIX_BITS: u32 = 12;

/// Points or keys per parallel work unit (bounding box, digit counts).
const CHUNK: usize = 1 << 16;

/// Smallest number of items per rayon task in element-wise passes.
const MIN_LEN: usize = 1 << 12;

/// Faces per parallel work unit in the face pass of [`cluster`].
const FACE_CHUNK: usize = 1 << 14;

/// Marks a dropped face in the first corner of its remapped triple (vertex counts are
/// below `u32::MAX`, so no vertex has this index).
const DROPPED: u32 = u32::MAX;

/// Largest `B` whose packed key `x << 2B | y << B | z` fits a `u64`.
const MAX_KEY_BITS: u32 = 21;

/// How the step is chosen from the box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridKind {
    /// One step `S / (2^B - 1)` on every axis, `S` the largest box side.
    Cube,
    /// A step `(max_a - min_a) / (2^B - 1)` per axis.
    Axes,
}

/// Which faces count as repeats of an earlier face in [`cluster`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Duplicates {
    /// Keep every non-degenerate face.
    Keep,
    /// Drop a face whose corners are an earlier kept face's corners in the same cyclic
    /// order (`(a, b, c)`, `(b, c, a)`, `(c, a, b)`); the opposite winding is kept.
    Oriented,
    /// Drop a face whose corner set equals an earlier kept face's, whatever the order.
    Any,
}

/// A quantization grid: box, bits and step. Build it with [`Grid::new`] or
/// [`Grid::bounding`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Bits per coordinate, `1..=32`.
    pub bits: u32,
    /// Box min corner: the position of corner code `(0, 0, 0)` (length).
    pub min: [f64; 3],
    /// Box max corner (length). Points beyond it are refused.
    pub max: [f64; 3],
    /// Length of one code unit per axis (length); 0 on an axis of zero extent.
    pub step: [f64; 3],
    /// `1 / step` per axis where that is a normal f64, else 0 (see [`axis_code`]).
    inv_step: [f64; 3],
}

/// Refuses bit counts outside `1..=32`.
pub fn check_bits(bits: u32) -> Result<(), MeshError> {
    if (1..=MAX_BITS).contains(&bits) {
        Ok(())
    } else {
        Err(MeshError::Parameter(format!(
            "bits must be an integer from 1 to {MAX_BITS}, got {bits}"
        )))
    }
}

/// `2^B - 1`, the largest corner code.
#[inline]
#[must_use]
pub fn max_code(bits: u32) -> u32 {
    debug_assert!((1..=MAX_BITS).contains(&bits));
    ((1u64 << bits) - 1) as u32
}

/// Relative distance from `y' = (x - min) * (1 / step)` to a half-integer below which
/// [`axis_code`] divides instead (see there).
const RECIPROCAL_SLACK: f64 = 1.0 / (1u64 << 45) as f64;

/// `2^52`: adding and subtracting it rounds an f64 of magnitude below `2^51` to the nearest
/// integer (ties to even), and `(q + 2^52).to_bits()` holds an integer `0 <= q < 2^32` in
/// its low 32 bits.
const ROUNDING_MAGIC: f64 = (1u64 << 52) as f64;

/// One coordinate's code as an f64 (exact: codes are below `2^32`; [`code_bits`] gives
/// the integer): `round((x - min) / step)` with `y = (x - min) / step` the correctly
/// rounded f64 quotient, halves up, clamped to `[0, top]`; 0 when the step is 0.
///
/// A division costs several multiplications and float-to-integer conversions several
/// instructions, so `y' = (x - min) * inv_step` is tried first, with `inv_step` the f64
/// value of `1 / step` (0 when that is not a normal number), rounded to the nearest
/// integer with [`ROUNDING_MAGIC`]. Two roundings separate `y'` from the exact
/// `(x - min) / step` and one separates `y`, so `|y' - y| <= 3.01 * 2^-53 * y' <
/// 2^-50 * y'`: unless `y'` lies within [`RECIPROCAL_SLACK`]` * y'` of a half-integer
/// (where ties and the two quotients could round apart), `y` rounds to the same integer
/// as `y'`, halves up or to nearest alike. Only those rare points, and the ones outside
/// the box, take the exact path: `t = trunc(y)` is `floor(y)` for `y >= 0`, and
/// `t + (y - t >= 0.5)` rounds halves up (`y - t` is exact). The codes are exactly the
/// division's.
#[inline]
#[must_use]
fn axis_code(x: f64, min: f64, step: f64, inv_step: f64, top: u32) -> f64 {
    if step > 0.0 {
        let d = x - min;
        let fast = d * inv_step;
        let nearest = (fast + ROUNDING_MAGIC) - ROUNDING_MAGIC;
        let q = if inv_step > 0.0 && ((fast - nearest).abs() - 0.5).abs() > RECIPROCAL_SLACK * fast
        {
            nearest
        } else {
            let y = d / step;
            let t = y as i64; // saturating; negative y (outside the box) clamps to 0 below
            t.saturating_add(i64::from(y - t as f64 >= 0.5)) as f64
        };
        let top = f64::from(top);
        let q = if q > top { top } else { q };
        if q > 0.0 { q } else { 0.0 }
    } else {
        0.0
    }
}

impl Grid {
    /// The grid on the box `[min, max]`.
    ///
    /// Refuses bits outside `1..=32`, non-finite corners, `min > max` on an axis, a side
    /// that overflows f64, and a positive side whose step underflows.
    pub fn new(bits: u32, kind: GridKind, min: [f64; 3], max: [f64; 3]) -> Result<Self, MeshError> {
        check_bits(bits)?;
        if !min.iter().chain(max.iter()).all(|c| c.is_finite()) {
            return Err(MeshError::Parameter(format!(
                "box corners must be finite, got min {min:?} and max {max:?}"
            )));
        }
        let mut side = [0.0; 3];
        for a in 0..3 {
            if min[a] > max[a] {
                return Err(MeshError::Parameter(format!(
                    "box min exceeds box max on axis {a}: {} > {}",
                    min[a], max[a]
                )));
            }
            side[a] = max[a] - min[a];
            if !side[a].is_finite() {
                return Err(MeshError::Parameter(format!(
                    "box side on axis {a} overflows float64 ({} to {})",
                    min[a], max[a]
                )));
            }
        }
        let levels = f64::from(max_code(bits));
        let largest = side.iter().copied().fold(0.0, f64::max);
        let step = match kind {
            GridKind::Cube => [largest / levels; 3],
            GridKind::Axes => [side[0] / levels, side[1] / levels, side[2] / levels],
        };
        for a in 0..3 {
            let needed = if kind == GridKind::Cube {
                largest
            } else {
                side[a]
            };
            if needed > 0.0 && step[a] < f64::MIN_POSITIVE {
                return Err(MeshError::Parameter(format!(
                    "box side {needed:e} on axis {a} is too small to split into 2^{bits} - 1 \
                     float64 steps"
                )));
            }
        }
        let inv_step = step.map(|s| {
            let inv = 1.0 / s;
            if inv.is_normal() { inv } else { 0.0 }
        });
        Ok(Grid {
            bits,
            min,
            max,
            step,
            inv_step,
        })
    }

    /// The grid on the bounding box of `vertices` (all of them).
    pub fn bounding(vertices: &[[f64; 3]], bits: u32, kind: GridKind) -> Result<Self, MeshError> {
        check_bits(bits)?;
        if vertices.is_empty() {
            return Err(MeshError::Empty(
                "no vertices to quantize: the bounding box is undefined".into(),
            ));
        }
        let Some((min, max)) = bounding_box(vertices) else {
            check_finite(vertices)?;
            return Err(MeshError::Parameter(
                "a coordinate failed the finite test but passes check_finite".into(),
            ));
        };
        Grid::new(bits, kind, min, max)
    }

    /// `2^B - 1`, the largest corner code.
    #[inline]
    #[must_use]
    pub fn max_code(&self) -> u32 {
        max_code(self.bits)
    }

    /// `S`, the largest side of the box (length).
    #[must_use]
    pub fn grid_size(&self) -> f64 {
        (0..3)
            .map(|a| self.max[a] - self.min[a])
            .fold(0.0, f64::max)
    }

    /// `|step| / 2`: the largest distance from a point of the box to its grid point
    /// (length); `(sqrt(3) / 2) * s` on the cube grid.
    #[must_use]
    pub fn bound(&self) -> f64 {
        0.5 * self.step.iter().map(|s| s * s).sum::<f64>().sqrt()
    }

    /// `2^(B-1) - 1`: centred code = corner code minus this offset (paper Sec. 8).
    #[inline]
    #[must_use]
    pub fn centered_offset(&self) -> u32 {
        (1u32 << (self.bits - 1)) - 1
    }

    /// True when `p` lies in the closed box (false for NaN).
    #[inline]
    #[must_use]
    pub fn contains(&self, p: &[f64; 3]) -> bool {
        let (lo, hi) = (&self.min, &self.max);
        // Non-short-circuit `&`: branch-free.
        (lo[0] <= p[0])
            & (p[0] <= hi[0])
            & (lo[1] <= p[1])
            & (p[1] <= hi[1])
            & (lo[2] <= p[2])
            & (p[2] <= hi[2])
    }

    /// Corner code of a point of the box.
    #[inline]
    #[must_use]
    pub fn code(&self, p: &[f64; 3]) -> [u32; 3] {
        self.code_and_squared_displacement(p).0
    }

    /// The corner code of a point of the box and its squared displacement
    /// `|p - position(code)|^2` (squared length), both as [`Grid::code`] and
    /// [`Grid::position`] give them.
    #[inline]
    #[must_use]
    fn code_and_squared_displacement(&self, p: &[f64; 3]) -> ([u32; 3], f64) {
        let (top, m, s, r) = (self.max_code(), &self.min, &self.step, &self.inv_step);
        let q = [
            axis_code(p[0], m[0], s[0], r[0], top),
            axis_code(p[1], m[1], s[1], r[1], top),
            axis_code(p[2], m[2], s[2], r[2], top),
        ];
        let x = [m[0] + q[0] * s[0], m[1] + q[1] * s[1], m[2] + q[2] * s[2]];
        let code = [code_bits(q[0]), code_bits(q[1]), code_bits(q[2])];
        (code, squared_distance(p, &x))
    }

    /// Dequantised position `min + q * step` of a corner code (length).
    #[inline]
    #[must_use]
    pub fn position(&self, q: &[u32; 3]) -> [f64; 3] {
        let (m, s) = (&self.min, &self.step);
        [
            m[0] + f64::from(q[0]) * s[0],
            m[1] + f64::from(q[1]) * s[1],
            m[2] + f64::from(q[2]) * s[2],
        ]
    }

    /// Refuses the first point (by index) outside the box.
    pub fn check_inside(&self, points: &[[f64; 3]]) -> Result<(), MeshError> {
        match points.iter().position(|p| !self.contains(p)) {
            Some(point) => Err(MeshError::OutsideBox { point }),
            None => Ok(()),
        }
    }

    /// Corner codes of `points`, and the largest distance from a point to its grid
    /// position (length; 0 for no point); refuses NaN/infinite coordinates, then points
    /// outside the box, naming the first offending point.
    pub fn codes(&self, points: &[[f64; 3]]) -> Result<(Vec<[u32; 3]>, f64), MeshError> {
        self.map_inside(points, |q| q)
    }

    /// Packed corner codes `x << 2B | y << B | z` of `points`, for `B <= 21` (the key fits
    /// a `u64`), and the largest displacement; refuses like [`Grid::codes`].
    pub fn keys(&self, points: &[[f64; 3]]) -> Result<(Vec<u64>, f64), MeshError> {
        debug_assert!(self.bits <= MAX_KEY_BITS);
        self.map_inside(points, |q| u64::pack(q, self.bits))
    }

    /// `f(code)` for every point and the largest displacement `|p - position(code)|`, in
    /// one parallel pass that also checks the box; refuses like [`Grid::codes`].
    fn map_inside<T: Copy + Send>(
        &self,
        points: &[[f64; 3]],
        f: impl Fn([u32; 3]) -> T + Sync,
    ) -> Result<(Vec<T>, f64), MeshError> {
        let mut out = uninit::<T>(points.len());
        let (outside, max_squared) = out
            .par_chunks_mut(MIN_LEN)
            .zip(points.par_chunks(MIN_LEN))
            .map(|(out, points)| {
                let (mut outside, mut max_squared) = (false, 0.0f64);
                for (o, p) in out.iter_mut().zip(points) {
                    outside |= !self.contains(p);
                    let (q, squared) = self.code_and_squared_displacement(p);
                    // Not `f64::max`, whose NaN handling costs instructions: a NaN
                    // (from a refused point) is simply not larger.
                    if squared > max_squared {
                        max_squared = squared;
                    }
                    *o = MaybeUninit::new(f(q));
                }
                (outside, max_squared)
            })
            .reduce(|| (false, 0.0), |a, b| (a.0 | b.0, a.1.max(b.1)));
        if outside {
            return Err(self.refusal(points));
        }
        // SAFETY: the chunks of `out` cover it, and every item was written.
        Ok((unsafe { assume_init(out) }, max_squared.sqrt()))
    }

    /// The error for points that failed [`Grid::contains`]: the first non-finite
    /// coordinate, else the first point outside the box.
    fn refusal(&self, points: &[[f64; 3]]) -> MeshError {
        match check_finite(points).and_then(|()| self.check_inside(points)) {
            Err(e) => e,
            Ok(()) => {
                MeshError::Parameter("a point failed the box test but passes both checks".into())
            }
        }
    }
}

/// Axis-aligned bounding box of non-empty points, or `None` when a coordinate is NaN or
/// infinite. Min and max are exact, so the result does not depend on the thread count.
#[must_use]
pub fn bounding_box(points: &[[f64; 3]]) -> Option<([f64; 3], [f64; 3])> {
    type Acc = ([f64; 3], [f64; 3], bool);
    fn grow(mut acc: Acc, lo: &[f64; 3], hi: &[f64; 3], finite: bool) -> Acc {
        for a in 0..3 {
            if lo[a] < acc.0[a] {
                acc.0[a] = lo[a];
            }
            if hi[a] > acc.1[a] {
                acc.1[a] = hi[a];
            }
        }
        acc.2 &= finite;
        acc
    }
    let empty = || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3], true);
    let (lo, hi, finite) = points
        .par_chunks(CHUNK)
        .map(|chunk| {
            chunk.iter().fold(empty(), |acc, p| {
                let finite = p[0].is_finite() & p[1].is_finite() & p[2].is_finite();
                grow(acc, p, p, finite)
            })
        })
        .reduce(empty, |acc, (lo, hi, finite)| grow(acc, &lo, &hi, finite));
    finite.then_some((lo, hi))
}

/// Euclidean distance between two points (length).
#[inline]
#[must_use]
fn distance(p: &[f64; 3], q: &[f64; 3]) -> f64 {
    squared_distance(p, q).sqrt()
}

/// `|p - q|^2` (squared length); `distance` is its square root, so maxima agree exactly.
#[inline]
fn squared_distance(p: &[f64; 3], q: &[f64; 3]) -> f64 {
    let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// Codes and dequantised positions of a point set.
#[derive(Debug, Clone)]
pub struct Quantized {
    /// Corner codes, `[0, 2^B - 1]` per axis.
    pub codes: Vec<[u32; 3]>,
    /// `min + code * step` (length).
    pub positions: Vec<[f64; 3]>,
    /// Largest distance between a point and its position (length); 0 for no point.
    pub max_displacement: f64,
}

/// Quantizes `points` on `grid`; refuses NaN/infinite coordinates and points outside
/// the grid's box (naming the first one).
pub fn quantize(points: &[[f64; 3]], grid: &Grid) -> Result<Quantized, MeshError> {
    let (codes, max_displacement) = grid.codes(points)?;
    let positions: Vec<[f64; 3]> = codes
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|q| grid.position(q))
        .collect();
    Ok(Quantized {
        codes,
        positions,
        max_displacement,
    })
}

/// Positions `origin + code * step` of integer codes (length).
///
/// Refuses non-finite `origin` or `step` and results that overflow f64. Codes of
/// magnitude above 2^53 are rounded to f64 first.
pub fn dequantize(
    codes: &[[i64; 3]],
    origin: [f64; 3],
    step: [f64; 3],
) -> Result<Vec<[f64; 3]>, MeshError> {
    if !origin.iter().chain(step.iter()).all(|c| c.is_finite()) {
        return Err(MeshError::Parameter(format!(
            "origin and step must be finite, got origin {origin:?} and step {step:?}"
        )));
    }
    let positions: Vec<[f64; 3]> = codes
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|q| {
            [
                origin[0] + q[0] as f64 * step[0],
                origin[1] + q[1] as f64 * step[1],
                origin[2] + q[2] as f64 * step[2],
            ]
        })
        .collect();
    match positions
        .iter()
        .position(|x| !x.iter().all(|c| c.is_finite()))
    {
        Some(i) => Err(MeshError::Parameter(format!(
            "code {i} = {:?} dequantizes beyond the float64 range",
            codes[i]
        ))),
        None => Ok(positions),
    }
}

/// Three codes of `bits` bits packed into one integer, `x` most significant, so that
/// integer order is the lexicographic order of codes; the LSD radix sort splits it into
/// digits.
trait PackedCode: Copy + Default + Eq + Send + Sync {
    /// `(self >> shift) & mask`.
    fn digit(self, shift: u32, mask: u32) -> usize;
    /// `x << 2B | y << B | z`.
    fn pack(q: [u32; 3], bits: u32) -> Self;
    /// Inverse of [`PackedCode::pack`].
    fn unpack(self, bits: u32) -> [u32; 3];
}

macro_rules! packed_code {
    ($t:ty) => {
        impl PackedCode for $t {
            #[inline]
            fn digit(self, shift: u32, mask: u32) -> usize {
                ((self >> shift) as u32 & mask) as usize
            }
            #[inline]
            fn pack(q: [u32; 3], bits: u32) -> Self {
                (<$t>::from(q[0]) << (2 * bits)) | (<$t>::from(q[1]) << bits) | <$t>::from(q[2])
            }
            #[inline]
            fn unpack(self, bits: u32) -> [u32; 3] {
                let mask = ((1 as $t) << bits) - 1;
                [
                    (self >> (2 * bits)) as u32,
                    ((self >> bits) & mask) as u32,
                    (self & mask) as u32,
                ]
            }
        }
    };
}
packed_code!(u32);
packed_code!(u64);
packed_code!(u128);

/// Stable LSD radix sort of `keys` (`key_bits` significant bits); returns the sorted keys
/// and, for each, its index in the input. Equal keys keep ascending input indices.
/// O(n * key_bits / 12); passes in which every key has the same digit are skipped.
fn radix_sort<K: PackedCode>(keys: Vec<K>, key_bits: u32) -> (Vec<K>, Vec<u32>) {
    let n = keys.len();
    let passes = key_bits.div_ceil(RADIX_BITS).max(1);
    let width = key_bits.div_ceil(passes);
    let buckets = 1usize << width;
    let mask = (buckets - 1) as u32;
    let counts = keys
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut c = vec![0usize; passes as usize * buckets];
            for &k in chunk {
                for p in 0..passes {
                    c[p as usize * buckets + k.digit(p * width, mask)] += 1;
                }
            }
            c
        })
        .reduce(
            || vec![0usize; passes as usize * buckets],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    let mut keys = keys;
    let mut index: Vec<u32> = (0..n as u32).collect();
    let mut keys_out = vec![K::default(); n];
    let mut index_out = vec![0u32; n];
    for p in 0..passes {
        let count = &counts[p as usize * buckets..(p as usize + 1) * buckets];
        if count.contains(&n) {
            continue;
        }
        let mut offset = Vec::with_capacity(buckets);
        let mut total = 0;
        for &c in count {
            offset.push(total);
            total += c;
        }
        for (&k, &i) in keys.iter().zip(&index) {
            let d = k.digit(p * width, mask);
            let o = offset[d];
            keys_out[o] = k;
            index_out[o] = i;
            offset[d] = o + 1;
        }
        std::mem::swap(&mut keys, &mut keys_out);
        std::mem::swap(&mut index, &mut index_out);
    }
    (keys, index)
}

/// Vertices grouped by equal code.
#[derive(Debug, Clone)]
pub struct Clusters {
    /// `id[i]`: vertex `i`'s cluster. Clusters are numbered in order of their smallest
    /// vertex index.
    pub id: Vec<u32>,
    /// `first[c]`: the smallest vertex index of cluster `c` (ascending in `c`).
    pub first: Vec<u32>,
    /// `code[c]`: the code shared by cluster `c`.
    pub code: Vec<[u32; 3]>,
}

impl Clusters {
    /// Number of clusters (distinct codes).
    #[inline]
    #[must_use]
    pub fn count(&self) -> usize {
        self.first.len()
    }
}

/// Groups packed codes: a radix sort puts equal keys in runs, in ascending vertex order;
/// a pass in vertex order then numbers each run when its first vertex is reached.
fn group_keys<K: PackedCode>(keys: Vec<K>, bits: u32) -> Clusters {
    let n = keys.len();
    let (sorted, index) = radix_sort(keys, 3 * bits);
    let mut run_of = vec![0u32; n];
    let mut run_first: Vec<u32> = Vec::new();
    let mut run_key: Vec<K> = Vec::new();
    for (j, (&k, &i)) in sorted.iter().zip(&index).enumerate() {
        if j == 0 || k != sorted[j - 1] {
            run_first.push(i);
            run_key.push(k);
        }
        run_of[i as usize] = (run_first.len() - 1) as u32;
    }
    drop((sorted, index));
    // A run's first vertex precedes its others, so its id exists when they are reached.
    let mut run_id = vec![0u32; run_first.len()];
    let mut first = Vec::with_capacity(run_first.len());
    let mut code = Vec::with_capacity(run_first.len());
    let id: Vec<u32> = run_of
        .iter()
        .enumerate()
        .map(|(i, &r)| {
            let r = r as usize;
            if run_first[r] as usize == i {
                run_id[r] = first.len() as u32;
                first.push(i as u32);
                code.push(run_key[r].unpack(bits));
            }
            run_id[r]
        })
        .collect();
    Clusters { id, first, code }
}

/// Fibonacci hashing: the top bits of `key * 2^64 / golden ratio` spread nearby grid codes
/// over the whole range.
#[inline]
fn spread(key: u64) -> u64 {
    key.wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Keys per partition that [`group_keys_partitioned`] aims at: its hash table (two to four
/// times as many slots of 8 or 16 bytes, 0.5 to 2 MiB) then stays in a core's L2 cache,
/// and the scatter writes few enough partitions at once (32 for a million vertices): with
/// 8192 keys per partition (128 partitions) the scatter took 2.5x longer at 655k
/// vertices, likely from TLB misses.
const PARTITION_TARGET: usize = 32768;

/// The integer `0 <= q < 2^32` held by the f64 `q`, without a conversion instruction.
#[inline]
#[must_use]
fn code_bits(q: f64) -> u32 {
    (q + ROUNDING_MAGIC).to_bits() as u32
}

/// A buffer of `len` uninitialized items, for one that is written in full before it is
/// read: `vec![x; len]` would first fill it (a pass over memory that the kernels then
/// write again).
fn uninit<T>(len: usize) -> Vec<MaybeUninit<T>> {
    let mut v = Vec::with_capacity(len);
    // SAFETY: the capacity is `len`, and `MaybeUninit` items need no initialization.
    unsafe { v.set_len(len) };
    v
}

/// The buffer of [`uninit`] once written.
///
/// # Safety
/// Every item of `v` is initialized.
unsafe fn assume_init<T>(v: Vec<MaybeUninit<T>>) -> Vec<T> {
    let mut v = std::mem::ManuallyDrop::new(v);
    // SAFETY: `MaybeUninit<T>` has the layout of `T`; the allocation, length and capacity
    // are `v`'s, which is not dropped; every item is initialized (the caller's contract).
    unsafe { Vec::from_raw_parts(v.as_mut_ptr().cast::<T>(), v.len(), v.capacity()) }
}

/// A slice that several threads write at disjoint indices.
#[derive(Clone, Copy)]
struct DisjointWrites<T>(*mut T, usize);

// SAFETY: only used for writes at indices that no two threads share (see the callers).
unsafe impl<T: Send> Send for DisjointWrites<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for DisjointWrites<T> {}

impl<T> DisjointWrites<T> {
    fn new(slice: &mut [T]) -> Self {
        Self(slice.as_mut_ptr(), slice.len())
    }

    /// # Safety
    /// No other thread writes or reads index `i` while the slice is shared.
    #[inline]
    unsafe fn write(self, i: usize, value: T) {
        assert!(i < self.1, "index {i} out of bounds {}", self.1);
        // SAFETY: in bounds (checked), and exclusive by the caller's contract.
        unsafe { self.0.add(i).write(value) }
    }
}

/// A vertex and its packed key, as [`group_keys_partitioned`] moves and stores them: one
/// `u64` `key << shift | vertex` when the key and the vertex index fit in 63 bits (the
/// usual case: `3 B + log2 n <= 63`), else a pair.
trait KeyedVertex: Copy + PartialEq + Send + Sync {
    /// Marks an empty hash-table slot; equal to no entry.
    const EMPTY: Self;
    fn new(key: u64, vertex: u32, shift: u32) -> Self;
    fn key(self, shift: u32) -> u64;
    fn vertex(self, shift: u32) -> u32;
}

impl KeyedVertex for u64 {
    const EMPTY: Self = u64::MAX;
    #[inline]
    fn new(key: u64, vertex: u32, shift: u32) -> Self {
        (key << shift) | u64::from(vertex)
    }
    #[inline]
    fn key(self, shift: u32) -> u64 {
        self >> shift
    }
    #[inline]
    fn vertex(self, shift: u32) -> u32 {
        (self & ((1u64 << shift) - 1)) as u32
    }
}

impl KeyedVertex for (u64, u32) {
    const EMPTY: Self = (u64::MAX, u32::MAX);
    #[inline]
    fn new(key: u64, vertex: u32, _: u32) -> Self {
        (key, vertex)
    }
    #[inline]
    fn key(self, _: u32) -> u64 {
        self.0
    }
    #[inline]
    fn vertex(self, _: u32) -> u32 {
        self.1
    }
}

/// Groups packed keys (`3 B <= 63` bits) in cache-friendly parallel passes:
///
/// 1. a stable counting sort on the top bits of [`spread`] splits the vertices into
///    partitions of about [`PARTITION_TARGET`] keys, equal keys in the same partition in
///    ascending vertex order (chunks of the input scatter in parallel, each at offsets
///    fixed by the counts of the chunks before it);
/// 2. each partition, in parallel, finds with a small open-addressing table the first
///    vertex `rep[i] <= i` that has vertex `i`'s key;
/// 3. the vertices with `rep[i] == i` (the first of their cluster) are numbered in vertex
///    order by per-chunk counts, and every other vertex takes its first's number.
///
/// Clusters come numbered by their smallest vertex index; nothing depends on the thread
/// count. Vertices and keys travel as one `u64` when they fit (see [`KeyedVertex`]).
fn group_keys_partitioned(keys: &[u64], bits: u32) -> Clusters {
    let n = keys.len();
    debug_assert!(3 * bits <= 63 && n < u32::MAX as usize);
    let shift = usize::BITS - n.saturating_sub(1).leading_zeros();
    let rep = if 3 * bits + shift <= 63 {
        representatives::<u64>(keys, shift)
    } else {
        representatives::<(u64, u32)>(keys, shift)
    };
    number_clusters(rep, keys, bits)
}

/// Steps 1 and 2 of [`group_keys_partitioned`]: `rep[i]`, the smallest vertex with vertex
/// `i`'s key.
fn representatives<E: KeyedVertex>(keys: &[u64], shift: u32) -> Vec<u32> {
    let n = keys.len();
    let part_bits = (n / PARTITION_TARGET)
        .max(1)
        .next_power_of_two()
        .trailing_zeros();
    let parts = 1usize << part_bits;
    let part_of = |k: u64| {
        if part_bits == 0 {
            0
        } else {
            (spread(k) >> (64 - part_bits)) as usize
        }
    };
    let chunk_counts: Vec<Vec<u32>> = keys
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut count = vec![0u32; parts];
            for &k in chunk {
                count[part_of(k)] += 1;
            }
            count
        })
        .collect();
    let mut start = vec![0usize; parts + 1];
    for count in &chunk_counts {
        for (p, &c) in count.iter().enumerate() {
            start[p + 1] += c as usize;
        }
    }
    for p in 0..parts {
        start[p + 1] += start[p];
    }
    let mut chunk_offsets = Vec::with_capacity(chunk_counts.len());
    let mut cursor = start[..parts].to_vec();
    for count in &chunk_counts {
        chunk_offsets.push(cursor.clone());
        for (c, &k) in cursor.iter_mut().zip(count) {
            *c += k as usize;
        }
    }
    let mut sorted = uninit::<E>(n);
    let out = DisjointWrites::new(&mut sorted);
    keys.par_chunks(CHUNK)
        .zip(chunk_offsets)
        .enumerate()
        .for_each(|(chunk_no, (chunk, mut offset))| {
            for (j, &k) in chunk.iter().enumerate() {
                let p = part_of(k);
                let vertex = (chunk_no * CHUNK + j) as u32;
                // SAFETY: chunk `c` writes partition `p` at
                // `[offset[c][p], offset[c][p] + count[c][p])`; these ranges are disjoint.
                unsafe { out.write(offset[p], MaybeUninit::new(E::new(k, vertex, shift))) };
                offset[p] += 1;
            }
        });
    // SAFETY: the chunks' ranges cover `0..n` (the counts sum to `n`).
    let sorted = unsafe { assume_init(sorted) };
    let mut rep = uninit::<u32>(n);
    let rep_out = DisjointWrites::new(&mut rep);
    // One table per worker, cleared for each partition: no allocation per partition.
    (0..parts)
        .into_par_iter()
        .for_each_init(Vec::new, |table, p| {
            let part = &sorted[start[p]..start[p + 1]];
            let slots = (2 * part.len()).next_power_of_two().max(8);
            let mask = slots - 1;
            let hash_shift = 64 - slots.trailing_zeros();
            // The first entry of each key; entries arrive in ascending vertex order.
            table.clear();
            table.resize(slots, E::EMPTY);
            for &e in part {
                let k = e.key(shift);
                let mut s = ((spread(k) << part_bits) >> hash_shift) as usize;
                let first = loop {
                    let slot = table[s];
                    if slot == E::EMPTY {
                        table[s] = e;
                        break e.vertex(shift);
                    }
                    if slot.key(shift) == k {
                        break slot.vertex(shift);
                    }
                    s = (s + 1) & mask;
                };
                // SAFETY: every vertex index appears in exactly one entry of `sorted`.
                unsafe { rep_out.write(e.vertex(shift) as usize, MaybeUninit::new(first)) };
            }
        });
    // SAFETY: as above, every index of `rep` was written once.
    unsafe { assume_init(rep) }
}

/// Step 3 of [`group_keys_partitioned`]: clusters numbered in order of their first vertex,
/// in three parallel passes over chunks (count the firsts; number them at their chunk's
/// offset; give every vertex its first's number, in place of `rep`).
fn number_clusters(mut rep: Vec<u32>, keys: &[u64], bits: u32) -> Clusters {
    let n = rep.len();
    let firsts: Vec<usize> = rep
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(chunk_no, chunk)| {
            let base = chunk_no * CHUNK;
            chunk
                .iter()
                .enumerate()
                .filter(|&(j, &r)| r as usize == base + j)
                .count()
        })
        .collect();
    let count = firsts.iter().sum();
    // `id` is written at the first vertex of each cluster only, and read only there.
    let mut id = uninit::<u32>(n);
    let mut first = uninit::<u32>(count);
    let mut code = uninit::<[u32; 3]>(count);
    let mut parts = Vec::with_capacity(firsts.len());
    let (mut first_rest, mut code_rest) = (&mut first[..], &mut code[..]);
    let mut offset = 0;
    for &f in &firsts {
        let (fp, fr) = first_rest.split_at_mut(f);
        let (cp, cr) = code_rest.split_at_mut(f);
        parts.push((offset, fp, cp));
        (first_rest, code_rest) = (fr, cr);
        offset += f;
    }
    id.par_chunks_mut(CHUNK)
        .zip(rep.par_chunks(CHUNK))
        .zip(parts)
        .enumerate()
        .for_each(|(chunk_no, ((id, rep), (offset, first, code)))| {
            let base = chunk_no * CHUNK;
            let mut k = 0;
            for (j, &r) in rep.iter().enumerate() {
                let i = base + j;
                if r as usize == i {
                    id[j] = MaybeUninit::new((offset + k) as u32);
                    first[k] = MaybeUninit::new(i as u32);
                    code[k] = MaybeUninit::new(keys[i].unpack(bits));
                    k += 1;
                }
            }
        });
    // SAFETY: `rep[i]` is the first vertex of `i`'s cluster, whose `id` was written.
    rep.par_iter_mut()
        .with_min_len(MIN_LEN)
        .for_each(|r| *r = unsafe { id[*r as usize].assume_init() });
    Clusters {
        id: rep,
        // SAFETY: chunk `c` wrote its `firsts[c]` clusters; these parts cover `0..count`.
        first: unsafe { assume_init(first) },
        // SAFETY: as for `first`.
        code: unsafe { assume_init(code) },
    }
}

/// Quantizes `points` on `grid` and groups them by code; returns the clusters and the
/// largest distance from a point to its grid position (length). Refuses like
/// [`Grid::codes`].
///
/// For `B <= 21` the packed codes are grouped by [`group_keys_partitioned`] (expected
/// O(n)); above, by a stable LSD radix sort of 128-bit keys (O(n B)) and a pass in vertex
/// order. Clusters are numbered by their smallest vertex index, for any thread count.
pub fn group_points(points: &[[f64; 3]], grid: &Grid) -> Result<(Clusters, f64), MeshError> {
    if grid.bits <= MAX_KEY_BITS {
        let (keys, max_displacement) = grid.keys(points)?;
        Ok((group_keys_partitioned(&keys, grid.bits), max_displacement))
    } else {
        let (codes, max_displacement) = grid.codes(points)?;
        Ok((group_codes_sorted(&codes, grid.bits), max_displacement))
    }
}

/// Groups vertices by code (see [`group_points`]).
#[must_use]
pub fn group_codes(codes: &[[u32; 3]], bits: u32) -> Clusters {
    debug_assert!((1..=MAX_BITS).contains(&bits));
    if bits <= MAX_KEY_BITS {
        let keys: Vec<u64> = codes
            .par_iter()
            .with_min_len(MIN_LEN)
            .map(|&q| u64::pack(q, bits))
            .collect();
        group_keys_partitioned(&keys, bits)
    } else {
        group_codes_sorted(codes, bits)
    }
}

/// Groups vertices by code with the radix sort of [`group_keys`] (any `bits`; the path
/// for `B > 21`, whose keys need 128 bits).
fn group_codes_sorted(codes: &[[u32; 3]], bits: u32) -> Clusters {
    fn packed<K: PackedCode>(codes: &[[u32; 3]], bits: u32) -> Clusters {
        group_keys(
            codes
                .par_iter()
                .with_min_len(MIN_LEN)
                .map(|&q| K::pack(q, bits))
                .collect(),
            bits,
        )
    }
    match 3 * bits {
        0..=32 => packed::<u32>(codes, bits),
        33..=64 => packed::<u64>(codes, bits),
        _ => packed::<u128>(codes, bits),
    }
}

/// The corners of a face in the canonical order of `mode`: rotated so that the smallest
/// comes first (`Oriented`) or sorted (`Any`).
#[inline]
#[must_use]
fn face_key(f: [u32; 3], mode: Duplicates) -> [u32; 3] {
    match mode {
        Duplicates::Any => {
            let mut s = f;
            s.sort_unstable();
            s
        }
        _ => {
            let m = if f[0] <= f[1] && f[0] <= f[2] {
                0
            } else if f[1] <= f[2] {
                1
            } else {
                2
            };
            [f[m], f[(m + 1) % 3], f[(m + 2) % 3]]
        }
    }
}

/// True when a triple repeats a corner.
#[inline]
#[must_use]
fn repeats_corner(t: &[u32; 3]) -> bool {
    (t[0] == t[1]) | (t[1] == t[2]) | (t[2] == t[0])
}

/// A clustered mesh and what clustering removed.
#[derive(Debug, Clone)]
pub struct Clustering {
    /// Dequantised grid positions of the kept clusters (length).
    pub vertices: Vec<[f64; 3]>,
    /// Corner codes of `vertices`.
    pub codes: Vec<[u32; 3]>,
    /// Kept faces, in input order, indexing `vertices`.
    pub faces: Vec<[u32; 3]>,
    /// For each kept face, its index among the input faces (ascending).
    pub face_index: Vec<u32>,
    /// For each input vertex, its output vertex, or -1 when its cluster was dropped.
    pub vertex_map: Vec<i64>,
    /// Input vertices that share another vertex's code: `n - clusters`.
    pub merged_vertices: usize,
    /// Clusters that no kept face uses: `clusters - vertices.len()`.
    pub unreferenced_vertices: usize,
    /// Faces with two equal corners after merging (including faces that repeated an
    /// index in the input).
    pub degenerate_faces: usize,
    /// Faces dropped as repeats of an earlier kept face (0 under [`Duplicates::Keep`]).
    pub duplicate_faces: usize,
    /// Largest distance from a kept input vertex (`vertex_map >= 0`) to its output
    /// vertex (length).
    pub max_displacement: f64,
}

/// The first `kept[c]` items of every chunk `c` of `FACE_CHUNK` items, in order, copied
/// in parallel.
///
/// # Safety
/// Those items are initialized (the others need not be).
unsafe fn gather_chunks<T: Copy + Send + Sync>(items: &[MaybeUninit<T>], kept: &[usize]) -> Vec<T> {
    let mut out = uninit::<T>(kept.iter().sum());
    let mut parts = Vec::with_capacity(kept.len());
    let mut rest = &mut out[..];
    for &k in kept {
        let (part, tail) = rest.split_at_mut(k);
        parts.push(part);
        rest = tail;
    }
    parts
        .into_par_iter()
        .zip(items.par_chunks(FACE_CHUNK))
        .for_each(|(part, chunk)| part.copy_from_slice(&chunk[..part.len()]));
    // SAFETY: the parts cover `out`, copied from initialized items (the caller's contract).
    unsafe { assume_init(out) }
}

/// The faces not marked DROPPED and their indices, in order: per-chunk counts give each
/// chunk its slice of the output, filled in parallel.
fn compact(mapped: &[[u32; 3]], kept: usize) -> (Vec<[u32; 3]>, Vec<u32>) {
    let counts: Vec<usize> = mapped
        .par_chunks(FACE_CHUNK)
        .map(|c| c.iter().filter(|t| t[0] != DROPPED).count())
        .collect();
    debug_assert_eq!(counts.iter().sum::<usize>(), kept);
    let mut out = vec![[0u32; 3]; kept];
    let mut index = vec![0u32; kept];
    let mut parts = Vec::with_capacity(counts.len());
    let (mut out_rest, mut index_rest) = (&mut out[..], &mut index[..]);
    for &c in &counts {
        let (o, o_rest) = out_rest.split_at_mut(c);
        let (i, i_rest) = index_rest.split_at_mut(c);
        parts.push((o, i));
        (out_rest, index_rest) = (o_rest, i_rest);
    }
    parts
        .into_par_iter()
        .zip(mapped.par_chunks(FACE_CHUNK))
        .enumerate()
        .for_each(|(chunk_no, ((o, i), chunk))| {
            // Write every face at the cursor and advance it only past kept ones: no
            // unpredictable branch when about half the faces collapse.
            let base = chunk_no * FACE_CHUNK;
            let mut k = 0;
            for (j, t) in chunk.iter().enumerate() {
                if k < o.len() {
                    o[k] = *t;
                    i[k] = (base + j) as u32;
                }
                k += usize::from(t[0] != DROPPED);
            }
        });
    (out, index)
}

/// Rossignac-Borrel vertex clustering on `grid`; see the module docs. Faces come as
/// `u32` or `i64` indices ([`VertexIndex`]).
///
/// Refuses an empty mesh, NaN/infinite coordinates, negative or out-of-range indices and
/// vertices outside the grid's box.
pub fn cluster<I: VertexIndex>(
    vertices: &[[f64; 3]],
    faces: &[[I; 3]],
    grid: &Grid,
    duplicates: Duplicates,
) -> Result<Clustering, MeshError> {
    let (n, m) = (vertices.len(), faces.len());
    if n == 0 || m == 0 {
        return Err(MeshError::Empty(format!(
            "mesh is empty ({n} vertices, {m} faces)"
        )));
    }
    if n >= DROPPED as usize || m > u32::MAX as usize {
        return Err(MeshError::Shape(format!(
            "{n} vertices and {m} faces exceed the supported maximum of 2^32 - 2"
        )));
    }
    let (clusters, max_displacement_all) = group_points(vertices, grid)?;
    let id = &clusters.id;
    let count = clusters.count();

    // One pass over the faces in parallel chunks: corners to cluster ids (checking the
    // indices), degenerate faces (two equal corners) dropped, kept faces packed at the
    // front of their chunk with their input index, then (while the chunk is in cache)
    // their clusters marked used. Every face is written at the chunk's cursor, which
    // only a kept face advances: no unpredictable branch when about half the faces
    // collapse.
    let used: Vec<AtomicBool> = (0..count).map(|_| AtomicBool::new(false)).collect();
    let mut packed = uninit::<[u32; 3]>(m);
    let mut packed_index = uninit::<u32>(m);
    let chunks: Vec<(usize, bool)> = packed
        .par_chunks_mut(FACE_CHUNK)
        .zip(packed_index.par_chunks_mut(FACE_CHUNK))
        .zip(faces.par_chunks(FACE_CHUNK))
        .enumerate()
        .map(|(chunk_no, ((out, out_index), chunk))| {
            let base = chunk_no * FACE_CHUNK;
            let (mut kept, mut bad) = (0, false);
            for (j, f) in chunk.iter().enumerate() {
                let (Some(&a), Some(&b), Some(&c)) = (
                    id.get(f[0].to_usize()),
                    id.get(f[1].to_usize()),
                    id.get(f[2].to_usize()),
                ) else {
                    bad = true;
                    continue;
                };
                out[kept] = MaybeUninit::new([a, b, c]);
                out_index[kept] = MaybeUninit::new((base + j) as u32);
                kept += usize::from(!repeats_corner(&[a, b, c]));
            }
            for t in &out[..kept] {
                // SAFETY: the first `kept` faces of the chunk were written above.
                for &k in unsafe { t.assume_init_ref() } {
                    used[k as usize].store(true, Ordering::Relaxed);
                }
            }
            (kept, bad)
        })
        .collect();
    if chunks.iter().any(|&(_, bad)| bad) {
        check_indices(faces, n)?;
    }
    let kept_per_chunk: Vec<usize> = chunks.iter().map(|&(kept, _)| kept).collect();
    let degenerate_faces = m - kept_per_chunk.iter().sum::<usize>();
    // Each chunk wrote its first `kept` items (all of them when no face was dropped).
    let (mut out_faces, mut face_index) = if degenerate_faces == 0 {
        // SAFETY: every chunk kept, so wrote, all its faces.
        unsafe { (assume_init(packed), assume_init(packed_index)) }
    } else {
        // SAFETY: chunk `c` wrote its first `kept_per_chunk[c]` items.
        unsafe {
            (
                gather_chunks(&packed, &kept_per_chunk),
                gather_chunks(&packed_index, &kept_per_chunk),
            )
        }
    };
    let mut duplicate_faces = 0;
    if duplicates != Duplicates::Keep {
        let mut keyed: Vec<([u32; 3], u32)> = out_faces
            .par_iter()
            .enumerate()
            .map(|(i, t)| (face_key(*t, duplicates), i as u32))
            .collect();
        // Positions are unique, so the order is total and the sort deterministic.
        keyed.par_sort_unstable();
        for w in keyed.windows(2) {
            if w[0].0 == w[1].0 {
                out_faces[w[1].1 as usize] = [DROPPED; 3];
                duplicate_faces += 1;
            }
        }
        if duplicate_faces > 0 {
            // A repeated face's clusters are its kept original's: `used` stays right.
            let (faces, position) = compact(&out_faces, out_faces.len() - duplicate_faces);
            face_index = position.iter().map(|&i| face_index[i as usize]).collect();
            out_faces = faces;
        }
    }

    let unreferenced_vertices = used
        .par_iter()
        .with_min_len(MIN_LEN)
        .filter(|u| !u.load(Ordering::Relaxed))
        .count();
    let positions = |codes: &[[u32; 3]]| -> Vec<[f64; 3]> {
        codes
            .par_iter()
            .with_min_len(MIN_LEN)
            .map(|q| grid.position(q))
            .collect()
    };
    let (vertex_map, out_codes, out_vertices, max_displacement) = if unreferenced_vertices == 0 {
        // Every cluster is kept, with its number: the code pass measured every vertex.
        let vertex_map: Vec<i64> = id
            .par_iter()
            .with_min_len(MIN_LEN)
            .map(|&c| i64::from(c))
            .collect();
        let out_vertices = positions(&clusters.code);
        (
            vertex_map,
            clusters.code,
            out_vertices,
            max_displacement_all,
        )
    } else {
        // New numbers by prefix count over the used clusters: kept ones keep their order.
        let mut new_id = vec![DROPPED; count];
        let mut kept: Vec<u32> = Vec::with_capacity(count - unreferenced_vertices);
        for (c, u) in used.iter().enumerate() {
            if u.load(Ordering::Relaxed) {
                new_id[c] = kept.len() as u32;
                kept.push(c as u32);
            }
        }
        out_faces
            .par_iter_mut()
            .with_min_len(MIN_LEN)
            .for_each(|t| {
                *t = [
                    new_id[t[0] as usize],
                    new_id[t[1] as usize],
                    new_id[t[2] as usize],
                ];
            });
        let vertex_map: Vec<i64> = id
            .par_iter()
            .with_min_len(MIN_LEN)
            .map(|&c| match new_id[c as usize] {
                DROPPED => -1,
                k => i64::from(k),
            })
            .collect();
        let out_codes: Vec<[u32; 3]> = kept
            .par_iter()
            .with_min_len(MIN_LEN)
            .map(|&c| clusters.code[c as usize])
            .collect();
        let out_vertices = positions(&out_codes);
        let max_displacement = vertices
            .par_iter()
            .with_min_len(MIN_LEN)
            .zip(&vertex_map)
            .map(|(p, &k)| {
                if k >= 0 {
                    distance(p, &out_vertices[k as usize])
                } else {
                    0.0
                }
            })
            .reduce(|| 0.0, f64::max);
        (vertex_map, out_codes, out_vertices, max_displacement)
    };
    let merged_vertices = n - count;

    Ok(Clustering {
        merged_vertices,
        unreferenced_vertices,
        degenerate_faces,
        duplicate_faces,
        max_displacement,
        vertices: out_vertices,
        codes: out_codes,
        faces: out_faces,
        face_index,
        vertex_map,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic 64-bit generator (SplitMix64) for test data.
    struct Mix(u64);

    impl Mix {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn unit_cube() -> Grid {
        Grid::new(2, GridKind::Cube, [0.0; 3], [3.0, 1.5, 0.0]).unwrap()
    }

    /// `round((x - min) / step)` halves up, by division and `floor` only: the reference
    /// for the reciprocal shortcut of `axis_code`. (`floor(y + 0.5)` would be wrong: the
    /// sum rounds `0.5 - 2^-54` up to 1.)
    fn divided_code(x: f64, min: f64, step: f64, top: u32) -> u32 {
        if step > 0.0 {
            let y = (x - min) / step;
            let q = y.floor() + if y - y.floor() >= 0.5 { 1.0 } else { 0.0 };
            q.clamp(0.0, f64::from(top)) as u32
        } else {
            0
        }
    }

    #[test]
    fn reciprocal_codes_equal_divided_codes_at_and_around_half_steps() {
        let mut rng = Mix(17);
        let mut near_half = 0;
        for trial in 0..3000 {
            let bits = 1 + (trial % 32) as u32;
            let min = (rng.unit() - 0.5) * 10f64.powi(trial % 19 - 9);
            let side = 10f64.powf(rng.unit() * 24.0 - 12.0);
            let g = Grid::new(bits, GridKind::Cube, [min; 3], [min + side; 3]).unwrap();
            let (step, top) = (g.step[0], g.max_code());
            for _ in 0..200 {
                let k = (rng.unit() * f64::from(top)).floor();
                let mut x = min + (k + 0.5) * step;
                if rng.unit() < 0.3 {
                    x = min + rng.unit() * side;
                }
                for x in [x.next_down(), x, x.next_up()] {
                    let x = x.clamp(min, min + side);
                    let fast = code_bits(axis_code(x, min, step, g.inv_step[0], top));
                    assert_eq!(fast, divided_code(x, min, step, top), "x {x:e} on {g:?}");
                    let y = (x - min) / step;
                    near_half += usize::from((y - y.floor() - 0.5).abs() < 1e-9);
                }
            }
        }
        assert!(
            near_half > 100_000,
            "only {near_half} points near a half step"
        );
    }

    #[test]
    fn corner_codes_round_halves_up_and_reach_the_top() {
        let g = unit_cube();
        assert_eq!(g.step, [1.0; 3]);
        assert_eq!(g.code(&[0.49, 0.5, 0.0]), [0, 1, 0]);
        assert_eq!(g.code(&[3.0, 1.5, 0.0]), [3, 2, 0]);
        assert_eq!(g.position(&[3, 2, 0]), [3.0, 2.0, 0.0]);
        assert!((g.bound() - 3f64.sqrt() / 2.0).abs() < 1e-15);
        assert_eq!(g.centered_offset(), 1);
    }

    #[test]
    fn axes_grid_has_one_step_per_axis_and_zero_on_flat_axes() {
        let g = Grid::new(3, GridKind::Axes, [0.0, 1.0, 5.0], [7.0, 15.0, 5.0]).unwrap();
        assert_eq!(g.step, [1.0, 2.0, 0.0]);
        assert_eq!(g.code(&[3.2, 8.9, 5.0]), [3, 4, 0]);
        assert_eq!(g.position(&[3, 4, 0]), [3.0, 9.0, 5.0]);
    }

    #[test]
    fn identical_points_get_code_zero_and_stay_exact() {
        let p = [[1e9 + 0.25, -3.0, 7.5]; 4];
        let g = Grid::bounding(&p, 12, GridKind::Cube).unwrap();
        let q = quantize(&p, &g).unwrap();
        assert!(q.codes.iter().all(|c| *c == [0, 0, 0]));
        assert_eq!(q.positions, p.to_vec());
        assert_eq!(q.max_displacement, 0.0);
        assert_eq!(g.bound(), 0.0);
    }

    #[test]
    fn bits_outside_one_to_thirty_two_and_bad_boxes_are_refused() {
        assert!(matches!(
            Grid::new(0, GridKind::Cube, [0.0; 3], [1.0; 3]),
            Err(MeshError::Parameter(_))
        ));
        assert!(matches!(
            Grid::new(33, GridKind::Cube, [0.0; 3], [1.0; 3]),
            Err(MeshError::Parameter(_))
        ));
        assert!(Grid::new(32, GridKind::Cube, [0.0; 3], [1.0; 3]).is_ok());
        assert!(Grid::new(8, GridKind::Cube, [0.0, 2.0, 0.0], [1.0; 3]).is_err());
        assert!(Grid::new(8, GridKind::Cube, [f64::NAN, 0.0, 0.0], [1.0; 3]).is_err());
        assert!(Grid::new(8, GridKind::Cube, [-1e308; 3], [1e308; 3]).is_err());
        assert!(Grid::new(8, GridKind::Axes, [0.0; 3], [1e-320, 1.0, 1.0]).is_err());
        let g = Grid::new(8, GridKind::Cube, [0.0; 3], [1.0; 3]).unwrap();
        assert_eq!(
            quantize(&[[0.5; 3], [1.0, 1.0, 1.5]], &g).unwrap_err(),
            MeshError::OutsideBox { point: 1 }
        );
        assert_eq!(
            quantize(&[[0.5, f64::INFINITY, 0.0]], &g).unwrap_err(),
            MeshError::NonFinite { vertex: 0 }
        );
    }

    #[test]
    fn non_finite_and_outside_points_are_named_not_swallowed() {
        let nan = [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [f64::NAN, 0.0, 0.0]];
        let inf = [[0.0, 0.0, 0.0], [f64::NEG_INFINITY, 0.0, 0.0]];
        assert_eq!(
            Grid::bounding(&nan, 8, GridKind::Cube),
            Err(MeshError::NonFinite { vertex: 2 })
        );
        assert_eq!(
            Grid::bounding(&inf, 8, GridKind::Axes),
            Err(MeshError::NonFinite { vertex: 1 })
        );
        let g = Grid::new(8, GridKind::Cube, [0.0; 3], [1.0; 3]).unwrap();
        let faces = [[0u32, 1, 2]];
        assert_eq!(
            cluster(&nan, &faces, &g, Duplicates::Keep).unwrap_err(),
            MeshError::NonFinite { vertex: 2 }
        );
        let outside = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [0.5, 1.5, 0.5]];
        assert_eq!(
            cluster(&outside, &faces, &g, Duplicates::Keep).unwrap_err(),
            MeshError::OutsideBox { point: 2 }
        );
        assert!(matches!(
            cluster(&outside[..2], &faces, &g, Duplicates::Keep),
            Err(MeshError::IndexOutOfRange {
                face: 0,
                index: 2,
                vertex_count: 2
            })
        ));
        let signed = [[0i64, 1, 0], [1, -1, 0]];
        assert!(matches!(
            cluster(&outside[..2], &signed, &g, Duplicates::Keep),
            Err(MeshError::IndexOutOfRange {
                face: 1,
                index: -1,
                vertex_count: 2
            })
        ));
    }

    #[test]
    fn thirty_two_bit_codes_are_exact_far_from_the_origin() {
        // Dyadic points 2^30 + k / 2^10: x - min is exact, so the codes do not see the offset.
        let near: Vec<[f64; 3]> = (0..50)
            .map(|k| [k as f64 / 1024.0, 0.0, (k * k % 17) as f64 / 1024.0])
            .collect();
        let far: Vec<[f64; 3]> = near
            .iter()
            .map(|p| p.map(|c| c + (1u64 << 30) as f64))
            .collect();
        let g_near = Grid::bounding(&near, 32, GridKind::Cube).unwrap();
        let g_far = Grid::bounding(&far, 32, GridKind::Cube).unwrap();
        assert_eq!(g_near.step, g_far.step);
        assert_eq!(
            quantize(&near, &g_near).unwrap().codes,
            quantize(&far, &g_far).unwrap().codes
        );
    }

    #[test]
    fn grouping_matches_a_brute_force_partition() {
        let mut rng = Mix(7);
        // Key widths u32 (3B <= 31), u64 (<= 63) and u128; shifted codes share their low
        // bits, so their keys differ only in high bits.
        let cases = [
            (0usize, 5u32, 0u32),
            (1, 1, 0),
            (1000, 3, 0),
            (3000, 10, 4),
            (5000, 11, 0),
        ];
        let more = [
            (4000, 12, 6),
            (3000, 21, 15),
            (3000, 22, 16),
            (2000, 32, 26),
            (2000, 32, 0),
        ];
        for &(n, bits, shift) in cases.iter().chain(&more) {
            let codes: Vec<[u32; 3]> = (0..n)
                .map(|_| {
                    [0, 1, 2].map(|_| (((rng.next() as u32) & 0x3f) << shift) & max_code(bits))
                })
                .collect();
            // Step 1: the points are their own codes.
            let top = f64::from(max_code(bits));
            let grid = Grid::new(bits, GridKind::Cube, [0.0; 3], [top; 3]).unwrap();
            let points: Vec<[f64; 3]> = codes.iter().map(|q| q.map(f64::from)).collect();
            let (clusters, max_displacement) = group_points(&points, &grid).unwrap();
            assert_eq!(max_displacement, 0.0, "points on the grid do not move");
            let mut firsts: Vec<u32> = Vec::new();
            for i in 0..n {
                let first = (0..=i).find(|&k| codes[k] == codes[i]).unwrap() as u32;
                if first as usize == i {
                    firsts.push(first);
                }
                let c = clusters.id[i] as usize;
                assert_eq!(clusters.first[c], first, "n={n} bits={bits} i={i}");
                assert_eq!(clusters.code[c], codes[i]);
            }
            assert_eq!(
                clusters.first, firsts,
                "clusters must be numbered by first vertex"
            );
            let sorted = group_codes_sorted(&codes, bits);
            assert_eq!(
                (&sorted.id, &sorted.first, &sorted.code),
                (&clusters.id, &clusters.first, &clusters.code),
                "partitioned and radix grouping must agree (bits={bits})"
            );
        }
    }

    #[test]
    fn partitioned_grouping_matches_the_radix_sort_on_many_chunks_and_partitions() {
        let mut rng = Mix(11);
        // 300k vertices: 5 input chunks, 16 partitions; few and many repeats; entries
        // packed in a u64 (B = 8, 14: 3 B + 19 <= 63) and as pairs (B = 16, 21).
        for (bits, range) in [(8u32, 0x3fu64), (14, 0x3fff), (16, 0xffff), (21, 0x1f_ffff)] {
            let codes: Vec<[u32; 3]> = (0..300_000)
                .map(|_| [0, 1, 2].map(|_| ((rng.next() & range) as u32) & max_code(bits)))
                .collect();
            let fast = group_codes(&codes, bits);
            let sorted = group_codes_sorted(&codes, bits);
            assert!(fast.count() > 1 && fast.count() <= codes.len());
            assert_eq!(fast.id, sorted.id, "bits={bits}");
            assert_eq!(fast.first, sorted.first, "bits={bits}");
            assert_eq!(fast.code, sorted.code, "bits={bits}");
        }
    }

    #[test]
    fn collapsing_a_thin_strip_drops_degenerate_and_duplicate_faces() {
        // Two triangles of a quad, plus the quad's mirror copy; at 1 bit the far corners
        // merge with the near ones in pairs.
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.25, 0.0],
            [0.0, 0.25, 0.0],
            [0.2, 0.0, 0.0],
        ];
        let f = [[0, 1, 2], [0, 2, 3], [0, 4, 1], [2, 1, 0], [1, 0, 2]];
        let g = Grid::new(4, GridKind::Cube, [0.0; 3], [1.0, 0.25, 0.0]).unwrap();
        // Step 1/15: codes x {0, 15, 15, 0, 3}, y {0, 0, 4, 4, 0}: nothing merges.
        let keep = cluster(&v, &f, &g, Duplicates::Keep).unwrap();
        assert_eq!(
            (
                keep.merged_vertices,
                keep.degenerate_faces,
                keep.duplicate_faces
            ),
            (0, 0, 0)
        );
        assert_eq!(keep.faces, f.to_vec());
        let oriented = cluster(&v, &f, &g, Duplicates::Oriented).unwrap();
        assert_eq!(oriented.face_index, vec![0, 1, 2, 3]);
        let any = cluster(&v, &f, &g, Duplicates::Any).unwrap();
        assert_eq!(any.face_index, vec![0, 1, 2]);
        assert_eq!(any.duplicate_faces, 2);

        // At 1 bit (step 1) vertices 3 and 4 merge into 0 and vertex 2 into 1 (y rounds to 0).
        let g1 = Grid::new(1, GridKind::Cube, [0.0; 3], [1.0, 0.25, 0.0]).unwrap();
        let c = cluster(&v, &f, &g1, Duplicates::Keep).unwrap();
        assert_eq!(c.merged_vertices, 3);
        assert_eq!(c.degenerate_faces, 5);
        assert!(c.faces.is_empty());
        assert_eq!(c.unreferenced_vertices, 2);
        assert_eq!(c.vertex_map, vec![-1; 5]);
    }

    #[test]
    fn output_vertices_follow_the_smallest_input_index_of_their_cluster() {
        let v = [
            [9.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 9.0, 0.0],
            [0.1, 0.0, 0.0],
            [5.0, 5.0, 0.0],
        ];
        let f = [[3i64, 0, 2], [4, 2, 0]];
        let g = Grid::bounding(&v, 3, GridKind::Cube).unwrap();
        let c = cluster(&v, &f, &g, Duplicates::Keep).unwrap();
        // Clusters {0}, {1, 3}, {2}, {4}; order of smallest index: 0, 1, 2, 4.
        assert_eq!(c.vertex_map, vec![0, 1, 2, 1, 3]);
        assert_eq!(c.faces, vec![[1, 0, 2], [3, 2, 0]]);
        assert_eq!(c.vertices[1], [0.0; 3]);
        assert_eq!(c.merged_vertices, 1);
        assert_eq!(c.unreferenced_vertices, 0);
        assert!(c.max_displacement <= g.bound());
    }

    #[test]
    fn clustering_keeps_every_vertex_on_the_grid_within_the_bound() {
        let mut rng = Mix(11);
        let v: Vec<[f64; 3]> = (0..400)
            .map(|_| [rng.unit(), rng.unit() * 0.5, rng.unit() * 0.25])
            .collect();
        let f: Vec<[u32; 3]> = (0..700)
            .map(|_| [0, 1, 2].map(|_| (rng.next() % 400) as u32))
            .collect();
        for bits in [1, 2, 4, 8, 16, 32] {
            for kind in [GridKind::Cube, GridKind::Axes] {
                let g = Grid::bounding(&v, bits, kind).unwrap();
                let c = cluster(&v, &f, &g, Duplicates::Any).unwrap();
                assert_eq!(
                    c.vertices.len() + c.merged_vertices + c.unreferenced_vertices,
                    v.len()
                );
                assert_eq!(
                    c.faces.len() + c.degenerate_faces + c.duplicate_faces,
                    f.len()
                );
                assert!(c.max_displacement <= g.bound() * (1.0 + 1e-12) + 1e-15);
                for (i, m) in c.vertex_map.iter().enumerate() {
                    if *m >= 0 {
                        assert_eq!(c.codes[*m as usize], g.code(&v[i]));
                    }
                }
                let mut used = vec![false; c.vertices.len()];
                for face in &c.faces {
                    assert!(face[0] != face[1] && face[1] != face[2] && face[0] != face[2]);
                    face.iter().for_each(|&i| used[i as usize] = true);
                }
                assert!(used.iter().all(|&u| u), "unreferenced output vertex");
            }
        }
    }

    #[test]
    fn dequantize_inverts_position_and_refuses_overflow() {
        let g = Grid::new(10, GridKind::Axes, [-1.0, 2.0, 3.0], [1.0, 4.0, 3.5]).unwrap();
        let q = [[0u32, 1023, 512], [7, 8, 9]];
        let codes: Vec<[i64; 3]> = q.iter().map(|c| c.map(i64::from)).collect();
        let x = dequantize(&codes, g.min, g.step).unwrap();
        assert_eq!(x, q.iter().map(|c| g.position(c)).collect::<Vec<_>>());
        assert!(dequantize(&[[i64::MAX, 0, 0]], [0.0; 3], [1e300; 3]).is_err());
        assert!(dequantize(&[[1, 0, 0]], [f64::NAN, 0.0, 0.0], [1.0; 3]).is_err());
    }
}
