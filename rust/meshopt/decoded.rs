//! What the decoders share: the 4-byte-aligned buffer they write ([`Decoded`]; the index
//! decoders and the filters write 16- and 32-bit integers in place), its length checked
//! against overflow, and their failures in words.

use crate::error::MeshError;

/// Decoded bytes, held in 4-byte-aligned storage: the index decoders and the filters
/// write 16- and 32-bit integers in place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decoded {
    words: Vec<u32>,
    len: usize,
}

impl Decoded {
    /// `len` zero bytes; an allocation that fails is refused, not an abort.
    pub(super) fn zeroed(len: usize) -> Result<Decoded, MeshError> {
        let n = len.div_ceil(4);
        let mut words = Vec::new();
        words.try_reserve_exact(n).map_err(|_| {
            MeshError::Parameter(format!("{len} bytes of decoded data do not fit in memory"))
        })?;
        words.resize(n, 0);
        Ok(Decoded { words, len })
    }

    /// A copy of `bytes` (for [`decode_filter`](super::decode_filter) on records decoded elsewhere).
    pub fn from_bytes(bytes: &[u8]) -> Result<Decoded, MeshError> {
        let mut out = Decoded::zeroed(bytes.len())?;
        out.as_bytes_mut().copy_from_slice(bytes);
        Ok(out)
    }

    /// The decoded bytes.
    pub fn as_bytes(&self) -> &[u8] {
        // SAFETY: `words` holds `4 * words.len() >= len` initialised bytes; `u8` has no
        // alignment requirement and no invalid values.
        unsafe { std::slice::from_raw_parts(self.words.as_ptr().cast::<u8>(), self.len) }
    }

    pub(super) fn as_bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: as in `as_bytes`; the slice borrows `self` mutably.
        unsafe { std::slice::from_raw_parts_mut(self.words.as_mut_ptr().cast::<u8>(), self.len) }
    }

    /// The storage, for a decoder or filter writing in place (`len` bytes, 4-byte aligned).
    pub(super) fn as_mut_ptr(&mut self) -> *mut std::ffi::c_void {
        self.words.as_mut_ptr().cast()
    }

    /// How many bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// `count * size`, refused when it overflows.
pub(super) fn decoded_len(count: usize, size: usize) -> Result<usize, MeshError> {
    count.checked_mul(size).ok_or_else(|| {
        MeshError::Parameter(format!(
            "{count} elements of {size} bytes overflow the address space"
        ))
    })
}

/// A stream shorter than the fewest bytes its declared elements need.
pub(super) fn too_short(
    codec: &str,
    data: &[u8],
    count: usize,
    what: &str,
    minimum: usize,
) -> MeshError {
    MeshError::Parameter(format!(
        "the meshopt {codec} stream has {} bytes, fewer than the {minimum} its {count} {what} \
         need at least: truncated or corrupt",
        data.len()
    ))
}

/// A C decoder's failure (its nonzero return code) in words.
pub(super) fn decoder_error(
    code: i32,
    codec: &str,
    data: &[u8],
    count: usize,
    what: &str,
) -> MeshError {
    let reason = match code {
        -1 => format!(
            "its header byte (0x{:02x}) is not one this decoder reads: not {codec} codec \
             data, or a newer version of it",
            data.first().copied().unwrap_or(0)
        ),
        -2 => format!("it ends before its {count} {what} are decoded: truncated or corrupt"),
        -3 => format!(
            "its bytes do not end where its {count} {what} do: truncated, corrupt, or its \
             count or byteStride is not the one it was written with"
        ),
        other => format!("the decoder failed (code {other}): corrupt"),
    };
    MeshError::Parameter(format!(
        "the meshopt {codec} stream ({} bytes) cannot be decoded: {reason}",
        data.len()
    ))
}
