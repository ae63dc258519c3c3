//! Work split into parts and run on a few OS threads: the host's builds of per-node
//! structures (skipping storage, node fields) cut by columns or planes, each part writing its
//! own piece of one output.
//!
//! Invariant: every part runs exactly once, and its result lands at its own index, whatever
//! the threads; a part that panics built nothing and stops no other.

use std::ops::Range;

/// `all` cut into consecutive pieces of `sizes` (the last piece short if they overrun).
pub fn split_sizes<E>(
    mut all: &mut [E],
    sizes: impl Iterator<Item = usize>,
) -> impl Iterator<Item = &mut [E]> {
    sizes.map(move |n| {
        let rest = std::mem::take(&mut all);
        let (piece, rest) = rest.split_at_mut(n.min(rest.len()));
        all = rest;
        piece
    })
}

/// `0..total` cut into `n` consecutive parts whose sizes differ by at most one.
pub fn even_parts(total: u32, n: u32) -> Vec<Range<u32>> {
    let n = n.max(1);
    let cut = |i: u32| (u64::from(i) * u64::from(total) / u64::from(n)) as u32;
    (0..n).map(|i| cut(i)..cut(i + 1)).collect()
}

/// One part of a skipping build, saying whether it built.
pub type Part<'a> = Box<dyn FnOnce() -> bool + Send + 'a>;

/// Run `parts` on up to `threads` OS threads, the calling thread one of them, each taking the
/// next part no thread has taken; whether each built (a part that panics built nothing).
/// One thread a part put three threads on two cores for a paper view's masks and leap map,
/// and left the calling thread waiting.
pub fn run_parts(parts: Vec<Part<'_>>, threads: usize) -> Vec<bool> {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::sync::Mutex;
    let built: Vec<AtomicBool> = parts.iter().map(|_| AtomicBool::new(false)).collect();
    let parts: Vec<Mutex<Option<Part<'_>>>> =
        parts.into_iter().map(|p| Mutex::new(Some(p))).collect();
    let next = AtomicUsize::new(0);
    let work = || loop {
        let i = next.fetch_add(1, Ordering::Relaxed);
        let Some(slot) = parts.get(i) else {
            return;
        };
        let part = slot
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .take();
        if let Some(part) = part {
            let ok = std::panic::catch_unwind(std::panic::AssertUnwindSafe(part));
            built[i].store(ok.unwrap_or(false), Ordering::Relaxed);
        }
    };
    let helpers = threads.min(parts.len()).saturating_sub(1);
    std::thread::scope(|scope| {
        for _ in 0..helpers {
            scope.spawn(work);
        }
        work();
    });
    built.into_iter().map(AtomicBool::into_inner).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// Every part runs exactly once, on any number of threads, and its result lands at its
    /// own index; a part that panics built nothing and stops no other.
    #[test]
    fn each_part_runs_once_and_reports_in_order() {
        for threads in [0, 1, 2, 3, 8] {
            for n in [0usize, 1, 2, 5, 9] {
                let runs: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(0)).collect();
                let parts = (0..n)
                    .map(|i| -> Part<'_> {
                        let runs = &runs;
                        Box::new(move || {
                            runs[i].fetch_add(1, Ordering::Relaxed);
                            assert!(i != 4, "part 4 fails");
                            i % 2 == 0
                        })
                    })
                    .collect();
                let built = run_parts(parts, threads);
                let expected: Vec<bool> = (0..n).map(|i| i % 2 == 0 && i != 4).collect();
                assert_eq!(built, expected, "{n} parts on {threads} threads");
                assert!(runs.iter().all(|r| r.load(Ordering::Relaxed) == 1));
            }
        }
    }
}
