//! A file read through a memory map, whose pages are released once parsed.

use std::fs::File;
use std::path::Path;

use memmap2::Mmap;

/// Bytes per chunk a worker parses before it releases the chunk's pages: small enough
/// that the mapped pages resident at once stay a few MB per thread, large enough that
/// one `madvise` call per chunk costs nothing.
pub const CHUNK_BYTES: usize = 4 << 20;

/// A read-only memory map of a whole file (`None` for an empty file, which cannot be
/// mapped), or bytes already in memory.
pub struct Mapped {
    map: Option<Mmap>,
    owned: Vec<u8>,
}

impl Mapped {
    /// Maps the file at `path`.
    ///
    /// # Errors
    /// When the file cannot be opened or mapped.
    pub fn open(path: &Path) -> std::io::Result<Mapped> {
        let file = File::open(path)?;
        if file.metadata()?.len() == 0 {
            return Ok(Mapped::from_bytes(Vec::new()));
        }
        // SAFETY: the map is read-only; a file truncated while mapped would raise SIGBUS,
        // the same hazard as any reader of a file another process rewrites (numpy.memmap,
        // Python's mmap), and the readers here only read.
        let map = unsafe { Mmap::map(&file)? };
        Ok(Mapped {
            map: Some(map),
            owned: Vec::new(),
        })
    }

    /// Bytes already in memory, read as a mapped file would be.
    #[must_use]
    pub fn from_bytes(owned: Vec<u8>) -> Mapped {
        Mapped { map: None, owned }
    }

    /// The file's bytes.
    #[must_use]
    pub fn bytes(&self) -> &[u8] {
        self.map.as_deref().unwrap_or(&self.owned)
    }

    /// Drops the pages wholly inside `start..end` from this process's resident set (they
    /// stay in the page cache, and are read again if touched): the parsed part of the file
    /// then no longer counts in the peak memory.
    pub fn release(&self, start: usize, end: usize) {
        #[cfg(unix)]
        if let Some(map) = &self.map {
            let page = 4096;
            let from = start.div_ceil(page) * page;
            let to = (end.min(map.len()) / page) * page;
            if to > from {
                // SAFETY: a read-only shared file mapping: MADV_DONTNEED only drops the
                // page table entries, and a later read faults the same file bytes back in.
                let _ = unsafe {
                    map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, from, to - from)
                };
            }
        }
        #[cfg(not(unix))]
        let _ = (start, end);
    }
}
