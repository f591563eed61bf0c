//! Batches of independent lookups on every core ([`Threads`],
//! [`map_runs_on_threads`], [`fill_runs_on_threads`]).

use std::num::NonZeroUsize;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How many threads a batch call runs on.
///
/// Each result of a batch depends on its own input only, so the results
/// are bit-identical whatever the count; the count changes only the time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Threads {
    /// One a core the process may use
    /// ([`std::thread::available_parallelism`]); the default.
    #[default]
    EveryCore,
    /// Exactly this many; 1 runs on the calling thread only (for callers
    /// that run batches on threads of their own).
    Count(NonZeroUsize),
}

impl Threads {
    /// One thread: the calling one.
    pub const ONE: Threads = Threads::Count(NonZeroUsize::MIN);

    /// `0` for [`Threads::EveryCore`], else [`Threads::Count`].
    pub fn from_count(count: usize) -> Threads {
        NonZeroUsize::new(count).map_or(Threads::EveryCore, Threads::Count)
    }

    /// The number of threads this means on this machine.
    pub fn count(self) -> usize {
        match self {
            Threads::EveryCore => std::thread::available_parallelism().map_or(1, NonZeroUsize::get),
            Threads::Count(n) => n.get(),
        }
    }
}

/// Items a thread takes at a time: small enough that uneven costs (a
/// footprint over a whole texture beside a magnified one) balance, large
/// enough that taking one costs nothing.
const RUN: usize = 64;

/// Runs `run` over `items` cut into runs of [`RUN`] items, on `threads`
/// threads (the calling thread among them), and returns what the runs
/// appended, in the items' order. `run(part, out)` must append exactly one
/// output per item of `part`.
///
/// Threads take runs in turn from a shared counter, so the work balances
/// whatever each item costs; the output order is the items' own.
pub fn map_runs_on_threads<T: Sync, O: Send>(
    items: &[T],
    threads: Threads,
    run: impl Fn(&[T], &mut Vec<O>) + Sync,
) -> Vec<O> {
    if items.is_empty() {
        return Vec::new();
    }
    let runs = items.len().div_ceil(RUN);
    let threads = threads.count().min(runs);
    if threads <= 1 {
        let mut out = Vec::with_capacity(items.len());
        run(items, &mut out);
        return out;
    }
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<(usize, Vec<O>)>> = Mutex::new(Vec::with_capacity(runs));
    let work = || {
        let mut mine = Vec::new();
        loop {
            let k = next.fetch_add(1, Ordering::Relaxed);
            if k >= runs {
                break;
            }
            let part = &items[k * RUN..((k + 1) * RUN).min(items.len())];
            let mut out = Vec::with_capacity(part.len());
            run(part, &mut out);
            mine.push((k, out));
        }
        done.lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .extend(mine);
    };
    on_threads(threads, work);
    let mut done = done
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    done.sort_unstable_by_key(|(k, _)| *k);
    let mut out = Vec::with_capacity(items.len());
    for (_, part) in done {
        out.extend(part);
    }
    out
}

/// Runs `run` over `items` cut into runs of [`RUN`] items, on `threads`
/// threads (the calling thread among them), each run writing its items'
/// outputs into its own part of `out`, in the items' order: `out` holds
/// the same number of outputs for each item (`out.len()` a multiple of
/// `items.len()`; outputs past the last whole item are left as they are),
/// and `run(part, out)` writes them all.
///
/// What [`map_runs_on_threads`] returns, without gathering it afterwards:
/// each run writes in place, on the thread that computes it, so a batch
/// whose items cost little (a rectangle's integral, a third of a
/// microsecond) is not held back by one thread copying every output.
pub fn fill_runs_on_threads<T: Sync, O: Send>(
    items: &[T],
    out: &mut [O],
    threads: Threads,
    run: impl Fn(&[T], &mut [O]) + Sync,
) {
    if items.is_empty() {
        return;
    }
    let per_item = out.len() / items.len();
    let runs = items.len().div_ceil(RUN);
    let threads = threads.count().min(runs);
    let parts = items
        .chunks(RUN)
        .zip(out.chunks_mut((RUN * per_item).max(1)));
    if threads <= 1 {
        for (part, out) in parts {
            run(part, out);
        }
        return;
    }
    // Threads take the next run in turn, so the work balances whatever
    // each item costs (the lock is held only to take it).
    let next = Mutex::new(parts);
    let work = || {
        loop {
            let Some((part, out)) = next
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .next()
            else {
                break;
            };
            run(part, out);
        }
    };
    on_threads(threads, work);
}

/// Runs `work` on `threads` threads at once, the calling thread among
/// them, and returns when every one has finished.
fn on_threads(threads: usize, work: impl Fn() + Sync) {
    std::thread::scope(|scope| {
        for _ in 1..threads {
            scope.spawn(&work);
        }
        work();
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_come_back_in_order_whatever_the_thread_count() {
        let items: Vec<u64> = (0..1000).collect();
        let serial: Vec<u64> = items.iter().map(|x| x * x + 1).collect();
        for threads in [
            Threads::ONE,
            Threads::from_count(2),
            Threads::from_count(7),
            Threads::EveryCore,
        ] {
            let got = map_runs_on_threads(&items, threads, |part, out| {
                out.extend(part.iter().map(|x| x * x + 1));
            });
            assert_eq!(got, serial, "{threads:?}");
        }
        let none: Vec<u64> = map_runs_on_threads(&[] as &[u64], Threads::EveryCore, |_, _| {
            unreachable!("no run for no items")
        });
        assert!(none.is_empty());
        // In place: four outputs an item, each run writing its own part.
        let four: Vec<u64> = serial
            .iter()
            .flat_map(|&x| [x, x + 1, x + 2, x + 3])
            .collect();
        for threads in [Threads::ONE, Threads::from_count(3), Threads::EveryCore] {
            let mut got = vec![0u64; 4 * items.len()];
            fill_runs_on_threads(&items, &mut got, threads, |part, out| {
                for (x, out) in part.iter().zip(out.chunks_exact_mut(4)) {
                    let y = x * x + 1;
                    out.copy_from_slice(&[y, y + 1, y + 2, y + 3]);
                }
            });
            assert_eq!(got, four, "{threads:?}");
        }
        fill_runs_on_threads(
            &[] as &[u64],
            &mut [] as &mut [u64],
            Threads::EveryCore,
            |_, _| unreachable!("no run for no items"),
        );
        assert_eq!(Threads::from_count(0), Threads::EveryCore);
        assert!(Threads::EveryCore.count() >= 1);
    }
}
