//! The crate's global allocator: the system allocator, asking Linux for transparent huge
//! pages on large blocks.
//!
//! A BVH over a million triangles allocates a few hundred MB in blocks of 40 to 150 MB
//! (obvhs's nodes and work arrays, the prepared triangles, the sibling pairs), and touches
//! each 4 KiB page for the first time during the build: on the benchmark meshes a third of
//! the build time went to page faults. Linux's transparent huge pages are commonly in
//! `madvise` mode, so blocks of at least [`HUGE_BLOCK`] bytes are marked with
//! `madvise(MADV_HUGEPAGE)` right after allocation, before their first touch: the kernel
//! then backs them with 2 MiB pages (one fault per 2 MiB), which also spares the queries
//! TLB misses. glibc serves such blocks with their own `mmap`, so there the advice covers
//! that block alone; with another C library (musl, or a Python linked against jemalloc or
//! mimalloc through `LD_PRELOAD`) a large block may share pages with other memory, which
//! then gets huge pages too: harmless to correctness, at worst some memory. Everything else
//! is the system allocator unchanged; on other systems this is the system allocator.
//!
//! It is installed only in the extension module (the crate's `python` feature, see
//! `lib.rs`): a Rust program linking this library keeps its own global allocator.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks of at least this many bytes (32 MiB, glibc's largest `mmap` threshold) get the
/// huge-page advice.
pub const HUGE_BLOCK: usize = 32 << 20;

/// The system allocator with huge-page advice on large blocks.
pub struct HugePageAlloc;

/// Advises the kernel to back `[ptr, ptr + size)` with huge pages (the whole 4 KiB pages
/// inside it). Failure is harmless and ignored.
#[inline]
fn advise(ptr: *mut u8, size: usize) {
    #[cfg(target_os = "linux")]
    if !ptr.is_null() && size >= HUGE_BLOCK {
        const PAGE: usize = 4096;
        let start = (ptr as usize).next_multiple_of(PAGE);
        let end = (ptr as usize + size) & !(PAGE - 1);
        if end > start {
            // SAFETY: the range lies inside a block we own; madvise only changes how the
            // kernel backs it, never its contents.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, size);
}

// SAFETY: every call forwards to `System` with the same arguments; `advise` does not touch
// the memory.
unsafe impl GlobalAlloc for HugePageAlloc {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let ptr = unsafe { System.alloc(layout) };
        advise(ptr, layout.size());
        ptr
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let ptr = unsafe { System.alloc_zeroed(layout) };
        advise(ptr, layout.size());
        ptr
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let new = unsafe { System.realloc(ptr, layout, new_size) };
        advise(new, new_size);
        new
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn large_and_small_blocks_work() {
        let mut big = vec![0u8; super::HUGE_BLOCK + 12345];
        big[super::HUGE_BLOCK] = 7;
        big.resize(3 * super::HUGE_BLOCK, 1);
        assert_eq!(big[super::HUGE_BLOCK], 7);
        assert_eq!(big[3 * super::HUGE_BLOCK - 1], 1);
        let small: Vec<u64> = (0..1000).collect();
        assert_eq!(small.iter().sum::<u64>(), 499_500);
    }
}
