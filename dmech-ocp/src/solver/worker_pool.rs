//! The stage loops' worker threads, started once per process and kept.
//!
//! Why: a solve runs a few parallel loops per iteration (the derivative pass, the trial
//! points' values, the step's recovery) and a pipelined factorisation. Scoped threads
//! started for each cost a thread's creation and its fresh stack pages each time: about
//! 280 thread starts on the eight (some 100 loops of two threads, 77 factorisations of
//! one). Kept workers wait on a condition variable instead (after a short spin, [`SPIN`]),
//! and the calling thread works as one of them.
//!
//! One loop at a time uses the pool; a loop started while it is busy (another solver's
//! thread, or a loop inside a loop) runs on scoped threads of its own, as before.

use super::STAGE_THREAD_STACK;
use std::any::Any;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard, OnceLock, TryLockError};
use std::time::{Duration, Instant};

/// The loop's work, its lifetime erased: [`run`] does not return before every worker that
/// took it has finished, and no worker takes it after [`run`] stops handing it out.
type Job = &'static (dyn Fn() + Sync);

struct State {
    job: Option<Job>,
    /// Workers the current job still asks for.
    seats: usize,
    /// Workers running the current job.
    running: usize,
    /// Workers started so far (they live as long as the process).
    workers: usize,
    /// The first panic of a worker in the current job.
    panic: Option<Box<dyn Any + Send>>,
}

struct Pool {
    /// Held by the loop that uses the pool.
    busy: Mutex<()>,
    state: Mutex<State>,
    start: Condvar,
    finished: Condvar,
    /// `State::seats` and `State::running` as the holder of `state` last wrote them, for
    /// the waits that spin before they sleep ([`SPIN`]).
    seats: AtomicUsize,
    running: AtomicUsize,
}

/// How long a worker that has finished a job, and the caller waiting for the workers,
/// watch for the next event before sleeping on the condition variable. A sleeping thread
/// takes some 35 µs to wake on this project's 2-core virtual machine (a condition-variable
/// round trip: 70 µs median), and a solve runs about 300 loops: the helper woke late at
/// every loop's start and the caller at its end. Measured on the eight (farm-bench A/B
/// against no spin, 20 pairs): wall 0.966 at 100 µs, 0.952 at 300 µs, 0.977 at 1 ms;
/// 1.04 at 2 ms (a spinning core is not free on a shared virtual machine).
const SPIN: Duration = Duration::from_micros(300);

/// Spin until `done()` holds or [`SPIN`] has passed (the caller checks again under the lock).
fn spin_until(done: impl Fn() -> bool) {
    let t0 = Instant::now();
    while t0.elapsed() < SPIN {
        for _ in 0..64 {
            if done() {
                return;
            }
            std::hint::spin_loop();
        }
    }
}

impl Pool {
    fn state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

static POOL: OnceLock<Pool> = OnceLock::new();

fn pool() -> &'static Pool {
    POOL.get_or_init(|| Pool {
        busy: Mutex::new(()),
        state: Mutex::new(State {
            job: None,
            seats: 0,
            running: 0,
            workers: 0,
            panic: None,
        }),
        start: Condvar::new(),
        finished: Condvar::new(),
        seats: AtomicUsize::new(0),
        running: AtomicUsize::new(0),
    })
}

fn worker(pool: &'static Pool) {
    let mut st = pool.state();
    loop {
        if st.seats == 0 {
            drop(st);
            spin_until(|| pool.seats.load(Ordering::Acquire) > 0);
            st = pool.state();
        }
        while st.seats == 0 {
            st = pool.start.wait(st).unwrap_or_else(|p| p.into_inner());
        }
        st.seats -= 1;
        st.running += 1;
        pool.seats.store(st.seats, Ordering::Release);
        pool.running.store(st.running, Ordering::Release);
        let job = st.job.expect("a seat is offered with a job");
        drop(st);
        let outcome = catch_unwind(AssertUnwindSafe(job));
        st = pool.state();
        st.running -= 1;
        pool.running.store(st.running, Ordering::Release);
        if let Err(p) = outcome {
            st.panic.get_or_insert(p);
        }
        if st.running == 0 {
            pool.finished.notify_all();
        }
    }
}

/// Waits, also when the caller's own share of the work panics, until no worker runs the
/// job, after withdrawing the seats not yet taken (the caller's share ends only when the
/// shared queue is empty, so a late worker would find nothing to do).
struct Withdraw(&'static Pool);

impl Drop for Withdraw {
    fn drop(&mut self) {
        let pool = self.0;
        let mut st = pool.state();
        st.seats = 0;
        pool.seats.store(0, Ordering::Release);
        if st.running > 0 {
            drop(st);
            spin_until(|| pool.running.load(Ordering::Acquire) == 0);
            st = pool.state();
        }
        while st.running > 0 {
            st = self.0.finished.wait(st).unwrap_or_else(|p| p.into_inner());
        }
        st.job = None;
    }
}

/// `work()` on this thread and `helpers` kept workers at once. `work` must take its items
/// from a shared queue until it is empty (as the stage loops do): a worker that comes late
/// then finds nothing, and this thread's `work()` ends only when all items are handed out.
/// `false` (nothing run) when the pool is busy.
pub(super) fn run(helpers: usize, work: &(dyn Fn() + Sync)) -> bool {
    run_split(helpers, work, &mut || work())
}

/// `work()` on `helpers` kept workers while this thread runs `own()`; returns when both
/// are done. `own` must not return before the work is all handed out: the seats not yet
/// taken are then withdrawn. `false` (nothing run) when the pool is busy.
pub(super) fn run_split(helpers: usize, work: &(dyn Fn() + Sync), own: &mut dyn FnMut()) -> bool {
    let pool = pool();
    // A loop that panicked poisons `busy`; the pool itself is whole (`Withdraw` ran).
    let _busy = match pool.busy.try_lock() {
        Ok(g) => g,
        Err(TryLockError::Poisoned(p)) => p.into_inner(),
        Err(TryLockError::WouldBlock) => return false,
    };
    // SAFETY: the job is handed out only while `work` is borrowed here: `Withdraw` (also
    // on unwinding) stops handing it out and waits for every worker that took it.
    let job: Job = unsafe { std::mem::transmute::<&(dyn Fn() + Sync), Job>(work) };
    let guard = Withdraw(pool);
    {
        let mut st = pool.state();
        while st.workers < helpers {
            let spawned = std::thread::Builder::new()
                .name("dmech-stage".into())
                .stack_size(STAGE_THREAD_STACK)
                .spawn(move || worker(pool));
            if spawned.is_err() {
                break; // the threads that exist, and this one, do the work
            }
            st.workers += 1;
        }
        st.job = Some(job);
        st.seats = helpers.min(st.workers);
        st.panic = None;
        pool.seats.store(st.seats, Ordering::Release);
    }
    pool.start.notify_all();
    own();
    drop(guard);
    if let Some(p) = pool.state().panic.take() {
        resume_unwind(p);
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Every item of a shared queue is taken exactly once, over many loops in a row (the
    /// seats of one loop must not leak into the next).
    #[test]
    fn every_item_runs_once_per_loop() {
        for round in 0..200 {
            let next = AtomicUsize::new(0);
            let hits: Vec<AtomicUsize> = (0..97).map(|_| AtomicUsize::new(0)).collect();
            let work = || loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= hits.len() {
                    break;
                }
                hits[i].fetch_add(1, Ordering::Relaxed);
            };
            if !run(1 + round % 3, &work) {
                work(); // another test holds the pool
            }
            assert!(hits.iter().all(|h| h.load(Ordering::Relaxed) == 1));
        }
    }

    /// A worker's panic reaches the caller, and the pool works afterwards.
    #[test]
    fn a_worker_panic_reaches_the_caller() {
        let caller = std::thread::current().id();
        let worker_ran = std::sync::atomic::AtomicBool::new(false);
        let outcome = catch_unwind(|| {
            let work = || {
                if std::thread::current().id() != caller {
                    worker_ran.store(true, Ordering::Release);
                    panic!("worker");
                }
                // The caller's share lasts until a worker has taken its seat.
                while !worker_ran.load(Ordering::Acquire) {
                    std::thread::yield_now();
                }
            };
            while !run(1, &work) {
                std::thread::yield_now();
            }
        });
        assert!(outcome.is_err());
        let count = AtomicUsize::new(0);
        let work = || {
            count.fetch_add(1, Ordering::Relaxed);
        };
        while !run(1, &work) {
            std::thread::yield_now();
        }
        assert!((1..=2).contains(&count.load(Ordering::Relaxed)));
    }
}
