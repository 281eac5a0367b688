//! [`Progress`] (the workspace's one progress report, from `lgdm_base`) and parallel work that
//! reports it on the caller's thread.
//!
//! ```
//! use lgdm_pointcloud::Progress;
//! let mut last = None;
//! let mut on_progress = |p: Progress| last = Some((p.stage, p.done, p.total));
//! on_progress(Progress { stage: "views", done: 3, total: 10 });
//! assert_eq!(last, Some(("views", 3, 10)));
//! ```

pub use lgdm_base::Progress;

/// Runs `work(i, tick)` for every `i` in `0..n` on rayon's thread pool and returns the results
/// in index order (so the output never depends on the number of threads). Workers report
/// finished units with `tick(units)`; `on_units(units)` sees them on the calling thread only,
/// as they arrive, which is how the library's `&mut dyn FnMut(Progress)` callbacks keep being
/// called from the caller's thread.
///
/// Called from inside a rayon worker (a nested parallel call) the work still runs in parallel,
/// but the units are reported after it has finished: blocking a worker on the progress channel
/// could starve the pool.
pub(crate) fn par_map_with_progress<T: Send>(
    n: usize,
    work: impl Fn(usize, &dyn Fn(u64)) -> T + Sync,
    on_units: &mut dyn FnMut(u64),
) -> Vec<T> {
    use rayon::prelude::*;
    use std::sync::mpsc;

    let (tx, rx) = mpsc::channel::<u64>();
    let work = &work;
    let run = move || -> Vec<T> {
        (0..n)
            .into_par_iter()
            .map_with(tx, |tx, i| {
                work(i, &|units| {
                    // The receiver outlives every sender; a send cannot fail.
                    let _ = tx.send(units);
                })
            })
            .collect()
    };
    if rayon::current_thread_index().is_some() {
        let out = run();
        rx.try_iter().for_each(&mut *on_units);
        return out;
    }
    let mut out = None;
    rayon::in_place_scope(|scope| {
        let slot = &mut out;
        scope.spawn(move |_| *slot = Some(run()));
        // Ends when the last sender (inside `run`) is dropped, i.e. when the work is done.
        for units in rx {
            on_units(units);
        }
    });
    out.expect("the spawned job ran to completion")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_in_index_order_and_every_unit_reported_on_the_caller() {
        let caller = std::thread::current().id();
        let mut seen = 0u64;
        let out = par_map_with_progress(
            100,
            |i, tick| {
                tick(i as u64);
                i * i
            },
            &mut |u| {
                assert_eq!(std::thread::current().id(), caller);
                seen += u;
            },
        );
        assert_eq!(out, (0..100).map(|i| i * i).collect::<Vec<_>>());
        assert_eq!(seen, (0..100).sum::<u64>());
    }

    #[test]
    fn nested_calls_inside_the_pool_complete() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let (out, seen) = pool.install(|| {
            let mut seen = 0;
            let out = par_map_with_progress(
                10,
                |i, tick| {
                    tick(1);
                    i
                },
                &mut |u| seen += u,
            );
            (out, seen)
        });
        assert_eq!(out, (0..10).collect::<Vec<_>>());
        assert_eq!(seen, 10);
    }
}
