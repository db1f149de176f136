//! Three corner codes packed into one integer, `x` most significant, so that integer
//! order is the lexicographic order of codes: the key the grid computes
//! ([`Grid::keys`](super::Grid::keys)) and the clustering sorts and groups (`keys.rs`).

/// Largest `B` whose packed key `x << 2B | y << B | z` fits a `u64`.
pub(super) const MAX_KEY_BITS: u32 = 21;

/// Three codes of `bits` bits packed into one integer, `x` most significant, so that
/// integer order is the lexicographic order of codes; the LSD radix sort splits it into
/// digits.
pub(super) trait PackedCode: Copy + Default + Eq + Send + Sync {
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
