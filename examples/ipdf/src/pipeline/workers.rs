//! Training several models at once on threads of their own.
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::Error;

/// Runs `job` on every item, `workers` at a time on threads of their own (`workers` ≤ 1: in
/// turn, libtorch's threads unchanged). Where there are more items than workers, each worker
/// keeps an even share of libtorch's threads to the end: a worker that took one of the last
/// items with a larger share would put more threads to work than there are cores while the
/// others still train (the demo's last translation model once trained 4 times slower so).
/// Where there are no more, all start at once, item `i` of `n` with `1 / (n − i)` of the
/// threads: the mesh preset's translation model all of them beside its rotation model, which
/// trains faster once the translation model is done (docs/performance.md). Stops taking new
/// items after the first error, which it returns.
pub fn on_threads<T: Sync>(
    items: &[T],
    workers: usize,
    job: impl Fn(&T) -> Result<(), Error> + Sync,
) -> Result<(), Error> {
    if workers <= 1 {
        return items.iter().try_for_each(job);
    }
    let threads = tch::get_num_threads();
    let next = AtomicUsize::new(0);
    let work = || -> Result<(), Error> {
        loop {
            let index = next.fetch_add(1, Ordering::Relaxed);
            let Some(item) = items.get(index) else {
                return Ok(());
            };
            tch::set_num_threads((threads / share_of(items.len(), workers, index)).max(1));
            job(item).inspect_err(|_| next.store(items.len(), Ordering::Relaxed))?;
        }
    };
    let outcomes: Vec<Result<(), Error>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers).map(|_| scope.spawn(work)).collect();
        handles
            .into_iter()
            .map(|handle| {
                handle
                    .join()
                    .unwrap_or_else(|_| Err(Error::option("train", "a training thread panicked")))
            })
            .collect()
    });
    // libtorch's thread count is partly process-wide (MKL's): put it back for what follows.
    tch::set_num_threads(threads);
    outcomes.into_iter().collect()
}

/// How many workers share libtorch's threads while item `index` of `items` trains.
fn share_of(items: usize, workers: usize, index: usize) -> i32 {
    let sharing = if items > workers {
        workers
    } else {
        items - index
    };
    sharing.max(1) as i32
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Condvar, Mutex};

    use super::*;

    #[test]
    fn every_item_runs_once_whatever_the_workers() {
        for workers in [1, 2, 3, 8] {
            let done = Mutex::new(Vec::new());
            let items: Vec<usize> = (0..9).collect();
            on_threads(&items, workers, |&i| {
                done.lock().unwrap().push(i);
                Ok(())
            })
            .unwrap();
            let mut done = done.into_inner().unwrap();
            done.sort_unstable();
            assert_eq!(done, items, "{workers} workers");
        }
    }

    /// Set when the thread that owns it exits: a scoped worker thread exits only after its
    /// loop has returned, so after `on_threads` has stopped handing out items.
    struct OnExit(Arc<(Mutex<bool>, Condvar)>);

    impl Drop for OnExit {
        fn drop(&mut self) {
            let (flag, signal) = &*self.0;
            *flag.lock().unwrap() = true;
            signal.notify_all();
        }
    }

    thread_local! {
        static EXIT: std::cell::RefCell<Option<OnExit>> = const { std::cell::RefCell::new(None) };
    }

    #[test]
    fn the_first_error_stops_new_items_and_is_returned() {
        for workers in [1, 2, 3] {
            let started = Mutex::new(Vec::new());
            let failed_worker_gone = Arc::new((Mutex::new(false), Condvar::new()));
            let items: Vec<usize> = (0..50).collect();
            let outcome = on_threads(&items, workers, |&i| {
                started.lock().unwrap().push(i);
                if i == 3 {
                    // Marks this worker's exit, which follows the end of its loop.
                    EXIT.with(|exit| *exit.borrow_mut() = Some(OnExit(failed_worker_gone.clone())));
                    return Err(Error::option("item", format!("{i} failed")));
                }
                if i > 3 {
                    // Items after the failing one finish only once its worker has left.
                    let (flag, signal) = &*failed_worker_gone;
                    let _gone = signal
                        .wait_while(flag.lock().unwrap(), |gone| !*gone)
                        .unwrap();
                }
                Ok(())
            });
            assert_eq!(outcome.unwrap_err().to_string(), "item: 3 failed");
            // Items are handed out in order; once item 3 has failed, each other worker finishes
            // at most the one item it holds and takes no other.
            let mut started = started.into_inner().unwrap();
            started.sort_unstable();
            let expected: Vec<usize> = (0..started.len()).collect();
            assert_eq!(started, expected, "{workers} workers");
            assert!(
                started.len() <= 4 + (workers - 1),
                "{workers} workers: {started:?}"
            );
        }
    }

    #[test]
    fn shares_are_even_unless_every_item_starts_at_once() {
        // More items than workers: an even share to the end.
        assert!((0..15).all(|i| share_of(15, 2, i) == 2));
        assert!((0..7).all(|i| share_of(7, 3, i) == 3));
        // All at once: item i of n gets 1/(n − i) of the threads, the last all of them.
        assert_eq!(
            (0..2).map(|i| share_of(2, 2, i)).collect::<Vec<_>>(),
            [2, 1]
        );
        assert_eq!(
            (0..2).map(|i| share_of(2, 4, i)).collect::<Vec<_>>(),
            [2, 1]
        );
        assert_eq!(share_of(1, 2, 0), 1);
    }

    #[test]
    fn libtorch_threads_are_put_back() {
        let before = tch::get_num_threads();
        on_threads(&[0, 1, 2], 2, |_| Ok(())).unwrap();
        assert_eq!(tch::get_num_threads(), before);
    }
}
