//! Grid quantization to `B` bits per coordinate and vertex clustering (King & Rossignac
//! 1999, Sec. 1.1 and 3.3; Rossignac & Borrel's clustering, the paper's reference \[20\]).
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
//!
//! Files, one concept each, imports running one way (`faces` -> `keys` -> `grid` ->
//! `packed`): `grid.rs` (the box, its step and the rounding of coordinates to codes),
//! `packed.rs` (three codes packed into one integer), `keys.rs` (packed codes grouped into
//! clusters), `faces.rs` (the face pass of [`cluster`]: remapping, dropping collapsed and
//! repeated faces, compaction) and `buffers.rs` (the uninitialised and disjointly written
//! parallel buffers: the module's unsafe primitives, all in one place).

mod buffers;
mod faces;
mod grid;
mod keys;
mod packed;

pub use faces::{Clustering, Duplicates, cluster};
pub use grid::{
    Grid, GridKind, MAX_BITS, Quantized, bounding_box, check_bits, dequantize, max_code, quantize,
};
pub use keys::{Clusters, group_codes, group_points};

/// SplitMix64, the deterministic generator of the test data.
#[cfg(test)]
struct Mix(u64);

#[cfg(test)]
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
