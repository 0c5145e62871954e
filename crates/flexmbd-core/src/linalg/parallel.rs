//! Worker threads of the parallel sparse factorizations, one pool per process.
//!
//! faer runs `Par::rayon(n)` work on the rayon pool it is called from. Rayon's global pool
//! does not survive `fork`: a child process inherits the pool's bookkeeping but none of its
//! threads, so the first parallel call in the child waits for ever (Python's
//! `multiprocessing` forks by default on Linux, after the parent has preprocessed or
//! simulated). Parallel work therefore runs in a pool of our own, made on first use and made
//! anew when the process id changed (in a forked child); the parent's pool is left alone
//! there (its threads do not exist in the child, so it cannot be shut down).

use std::sync::{Arc, Mutex};

use rayon::{ThreadPool, ThreadPoolBuilder};

/// The pool of this process: (process id, thread count, pool).
static POOL: Mutex<Option<(u32, usize, Arc<ThreadPool>)>> = Mutex::new(None);

/// The pool of `threads` threads of this process, made if there is none yet, if it has
/// another size, or if it belongs to the parent of a forked process. None if the threads
/// cannot be started.
fn pool(threads: usize) -> Option<Arc<ThreadPool>> {
    let pid = std::process::id();
    let mut slot = POOL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((owner, count, pool)) = slot.as_ref() {
        if *owner == pid && *count == threads {
            return Some(pool.clone());
        }
    }
    let fresh = Arc::new(ThreadPoolBuilder::new().num_threads(threads).build().ok()?);
    if let Some((owner, _, stale)) = slot.replace((pid, threads, fresh.clone())) {
        if owner != pid {
            // A forked child: the parent's pool has no threads here; dropping it would
            // signal threads that do not exist.
            std::mem::forget(stale);
        }
    }
    Some(fresh)
}

/// Runs `work` with `threads` worker threads available to faer's `Par::rayon(threads)`:
/// in place for one thread, else in this process's pool (in place if its threads cannot be
/// started: faer then runs the parallel parts on the calling thread's pool).
pub fn install<R: Send>(threads: usize, work: impl FnOnce() -> R + Send) -> R {
    if threads <= 1 {
        return work();
    }
    match pool(threads) {
        Some(pool) => pool.install(work),
        None => work(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_runs_in_a_pool_of_the_size_asked_and_the_pool_is_kept() {
        assert_eq!(install(1, rayon::current_num_threads), rayon::current_num_threads());
        assert_eq!(install(3, rayon::current_num_threads), 3);
        let first = pool(3).unwrap();
        assert!(Arc::ptr_eq(&first, &pool(3).unwrap()));
        assert_eq!(install(2, rayon::current_num_threads), 2);
    }
}
