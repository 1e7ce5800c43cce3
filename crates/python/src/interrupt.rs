//! Running a render from Python: the worker threads of a call, and renders on a worker thread
//! with the GIL released that ctrl-c interrupts.

use crate::errors::scene_error;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use speckle::stats::Progress;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Cancels a render when asked.
struct Interrupt(AtomicBool);

impl Progress for Interrupt {
    fn cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// The worker threads of a call: `threads`, checked (`1..=speckle::stats::max_threads()`, else a
/// `SceneError` naming `threads`), or the global pool's.
pub(crate) fn thread_count(py: Python<'_>, threads: Option<usize>) -> PyResult<usize> {
    match threads {
        None => Ok(rayon::current_num_threads()),
        Some(t) => speckle::stats::check_threads(t)
            .map_err(|e| scene_error(py, format!("threads: {e}"), Some("threads".into()))),
    }
}

/// Runs `f` on a worker thread (on a pool of `threads` threads if given, else on the global
/// one) with the GIL released; the calling thread checks for signals every 50 ms and, on one
/// (ctrl-c), cancels the render, waits for it to stop and raises.
pub(crate) fn interruptible<T: Send>(
    py: Python<'_>,
    threads: Option<usize>,
    f: impl FnOnce(&dyn Progress) -> T + Send,
) -> PyResult<T> {
    let pool = match threads {
        None => None,
        Some(t) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(thread_count(py, Some(t))?)
                .build()
                .map_err(|e| PyRuntimeError::new_err(e.to_string()))?,
        ),
    };
    let stop = Interrupt(AtomicBool::new(false));
    let done = AtomicBool::new(false);
    let caller = std::thread::current();
    std::thread::scope(|scope| {
        let worker = scope.spawn(|| {
            let out = match &pool {
                Some(pool) => pool.install(|| f(&stop)),
                None => f(&stop),
            };
            done.store(true, Ordering::Release);
            caller.unpark();
            out
        });
        loop {
            py.detach(|| {
                if !done.load(Ordering::Acquire) {
                    std::thread::park_timeout(Duration::from_millis(50));
                }
            });
            if done.load(Ordering::Acquire) {
                break;
            }
            if let Err(e) = py.check_signals() {
                stop.0.store(true, Ordering::Relaxed);
                let _ = py.detach(|| worker.join());
                return Err(e);
            }
        }
        py.detach(|| worker.join())
            .map_err(|_| PyRuntimeError::new_err("the render panicked"))
    })
}
