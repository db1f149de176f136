//! Where kernels run: rayon's global pool, or a pool of a chosen size, safe across `fork`.
//!
//! A process forked after its parent started rayon's global pool inherits the pool's
//! bookkeeping but none of its threads: a job handed to it waits forever. Python's
//! `multiprocessing` pools on Linux, Celery's prefork workers and Gunicorn all fork. So
//! every kernel entry goes through [`run`], which compares the process id with the one
//! recorded when the first kernel ran: in a forked child the global pool is never touched,
//! and kernels run on a pool built in that child (one thread unless [`set_threads`] asked
//! for more, so that N forked workers do not start N times the cores in threads).

use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, TryLockError};

use rayon::{ThreadPool, ThreadPoolBuilder};

/// Worker threads for kernels: 0 means rayon's global pool (all cores) in the process that
/// first ran a kernel, one thread in a forked child.
static THREADS: AtomicUsize = AtomicUsize::new(0);

/// Process id of the first kernel call; 0 until then.
static OWNER: AtomicU32 = AtomicU32::new(0);

/// The pool built for an explicit thread count or for a forked child: `(process id,
/// threads, pool)`. A pool inherited from another process is never used.
static LOCAL: Mutex<Option<(u32, usize, Arc<ThreadPool>)>> = Mutex::new(None);

/// Sets the number of worker threads of every later kernel call (0: the default).
pub fn set_threads(threads: usize) {
    THREADS.store(threads, Ordering::Relaxed);
}

/// The count set by [`set_threads`] (0: the default).
#[must_use]
pub fn threads() -> usize {
    THREADS.load(Ordering::Relaxed)
}

/// True when this process is not the one that ran the first kernel: a forked child.
#[must_use]
pub fn is_forked_child() -> bool {
    let pid = std::process::id();
    let owner = match OWNER.compare_exchange(0, pid, Ordering::AcqRel, Ordering::Acquire) {
        Ok(_) => pid,
        Err(owner) => owner,
    };
    owner != pid
}

/// Runs `kernel` on a rayon pool: a worker of the global pool when no thread count was set
/// and this is not a forked child (the kernel's parallel loops then start without a
/// cross-thread handoff), else a pool of [`threads`] threads (one in a forked child when
/// none was set) built in this process. Fails only when threads cannot be started.
pub fn run<T, F>(kernel: F) -> Result<T, String>
where
    T: Send,
    F: FnOnce() -> T + Send,
{
    let forked = is_forked_child();
    let requested = threads();
    if requested == 0 && !forked {
        return Ok(rayon::scope(|_| kernel()));
    }
    let wanted = requested.max(1);
    Ok(local_pool(wanted, forked)?.install(kernel))
}

/// This process's pool of `threads` threads, built on first use and rebuilt when the
/// count changes.
fn local_pool(threads: usize, forked: bool) -> Result<Arc<ThreadPool>, String> {
    let build = || {
        ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map(Arc::new)
            .map_err(|e| format!("cannot start {threads} threads: {e}"))
    };
    let mut slot = match LOCAL.try_lock() {
        Ok(slot) => slot,
        Err(TryLockError::Poisoned(poisoned)) => poisoned.into_inner(),
        // In a forked child the lock may have been held, at the fork, by a thread that
        // does not exist here: it will never be released. Do without the cache.
        Err(TryLockError::WouldBlock) if forked => return build(),
        Err(TryLockError::WouldBlock) => LOCAL.lock().unwrap_or_else(|p| p.into_inner()),
    };
    let pid = std::process::id();
    if let Some((owner, count, pool)) = slot.as_ref()
        && *owner == pid
        && *count == threads
    {
        return Ok(Arc::clone(pool));
    }
    let pool = build()?;
    if let Some((owner, _, stale)) = slot.replace((pid, threads, Arc::clone(&pool)))
        && owner != pid
    {
        // A pool inherited through fork has no threads in this process: dropping it would
        // signal threads that do not exist. Leak it.
        std::mem::forget(stale);
    }
    Ok(pool)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    #[test]
    fn explicit_counts_run_on_a_pool_of_that_size() {
        for wanted in [1, 3, 2] {
            set_threads(wanted);
            let seen = run(rayon::current_num_threads).unwrap();
            assert_eq!(seen, wanted);
            let sum: u64 = run(|| (0..10_000u64).into_par_iter().sum()).unwrap();
            assert_eq!(sum, 49_995_000);
        }
        set_threads(0);
        assert!(!is_forked_child());
    }

    /// A child forked after the parent used the global pool runs kernels on a pool of its
    /// own; on the parent's it would wait forever.
    #[cfg(unix)]
    #[test]
    fn a_forked_child_does_not_hang() {
        let sum = || run(|| (0..100_000u64).into_par_iter().sum::<u64>()).unwrap();
        assert_eq!(sum(), 4_999_950_000);
        // SAFETY: the child only runs rayon work and leaves through `_exit`.
        let child = unsafe { libc::fork() };
        assert!(child >= 0, "fork failed");
        if child == 0 {
            let ok = is_forked_child() && sum() == 4_999_950_000;
            // SAFETY: ends the child without running the parent's test harness.
            unsafe { libc::_exit(if ok { 0 } else { 1 }) };
        }
        let mut status = 0;
        for _ in 0..600 {
            // SAFETY: waits for our own child without blocking.
            if unsafe { libc::waitpid(child, &mut status, libc::WNOHANG) } == child {
                assert!(libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0);
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        // SAFETY: stops the hung child.
        unsafe { libc::kill(child, libc::SIGKILL) };
        panic!("the forked child hung for 30 s");
    }
}
