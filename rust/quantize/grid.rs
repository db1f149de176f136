//! The quantization grid: its box and step, and the rounding of coordinates to corner codes
//! and back (see the [module docs](super) for the conventions).

use std::mem::MaybeUninit;

use rayon::prelude::*;

use super::buffers::{CHUNK, MIN_LEN, assume_init, uninit};
use super::packed::{MAX_KEY_BITS, PackedCode};
use crate::error::{MeshError, check_finite};

/// Largest supported bits per coordinate: codes are `u32`.
pub const MAX_BITS: u32 = 32;

/// How the step is chosen from the box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridKind {
    /// One step `S / (2^B - 1)` on every axis, `S` the largest box side.
    Cube,
    /// A step `(max_a - min_a) / (2^B - 1)` per axis.
    Axes,
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

/// The integer `0 <= q < 2^32` held by the f64 `q`, without a conversion instruction.
#[inline]
#[must_use]
fn code_bits(q: f64) -> u32 {
    (q + ROUNDING_MAGIC).to_bits() as u32
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
pub(super) fn distance(p: &[f64; 3], q: &[f64; 3]) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::super::Mix;
    use super::*;

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
