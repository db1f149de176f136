//! The parallel-buffer helpers of the quantization kernels, and with them every unsafe
//! primitive they use: buffers allocated without a fill pass and declared initialised once
//! written, and a slice several threads write at disjoint indices. The callers' `unsafe`
//! blocks only ever call these, each with a `SAFETY` comment stating why the contract holds.
//! The work-unit sizes of the parallel passes sit here too.

use std::mem::MaybeUninit;

use rayon::prelude::*;

/// Points or keys per parallel work unit (bounding box, digit counts).
pub(super) const CHUNK: usize = 1 << 16;

/// Smallest number of items per rayon task in element-wise passes.
pub(super) const MIN_LEN: usize = 1 << 12;

/// A buffer of `len` uninitialized items, for one that is written in full before it is
/// read: `vec![x; len]` would first fill it (a pass over memory that the kernels then
/// write again).
pub(super) fn uninit<T>(len: usize) -> Vec<MaybeUninit<T>> {
    let mut v = Vec::with_capacity(len);
    // SAFETY: the capacity is `len`, and `MaybeUninit` items need no initialization.
    unsafe { v.set_len(len) };
    v
}

/// The buffer of [`uninit`] once written.
///
/// # Safety
/// Every item of `v` is initialized.
pub(super) unsafe fn assume_init<T>(v: Vec<MaybeUninit<T>>) -> Vec<T> {
    let mut v = std::mem::ManuallyDrop::new(v);
    // SAFETY: `MaybeUninit<T>` has the layout of `T`; the allocation, length and capacity
    // are `v`'s, which is not dropped; every item is initialized (the caller's contract).
    unsafe { Vec::from_raw_parts(v.as_mut_ptr().cast::<T>(), v.len(), v.capacity()) }
}

/// A slice that several threads write at disjoint indices.
#[derive(Clone, Copy)]
pub(super) struct DisjointWrites<T>(*mut T, usize);

// SAFETY: only used for writes at indices that no two threads share (see the callers).
unsafe impl<T: Send> Send for DisjointWrites<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for DisjointWrites<T> {}

impl<T> DisjointWrites<T> {
    pub(super) fn new(slice: &mut [T]) -> Self {
        Self(slice.as_mut_ptr(), slice.len())
    }

    /// # Safety
    /// No other thread writes or reads index `i` while the slice is shared.
    #[inline]
    pub(super) unsafe fn write(self, i: usize, value: T) {
        assert!(i < self.1, "index {i} out of bounds {}", self.1);
        // SAFETY: in bounds (checked), and exclusive by the caller's contract.
        unsafe { self.0.add(i).write(value) }
    }
}

/// The first `kept[c]` items of every chunk `c` of `chunk` items, in order, copied in
/// parallel.
///
/// # Safety
/// Those items are initialized (the others need not be).
pub(super) unsafe fn gather_chunks<T: Copy + Send + Sync>(
    items: &[MaybeUninit<T>],
    chunk: usize,
    kept: &[usize],
) -> Vec<T> {
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
        .zip(items.par_chunks(chunk))
        .for_each(|(part, chunk)| part.copy_from_slice(&chunk[..part.len()]));
    // SAFETY: the parts cover `out`, copied from initialized items (the caller's contract).
    unsafe { assume_init(out) }
}
