//! Threads for short parallel steps: [`Helpers::for_each`] runs `work(0..n)`, each index once, on the
//! calling thread and the helpers, and returns when all are done.
//!
//! Built for the Gymnasium batch (docs/gymnasium.md, Throughput): a step of 256 episodes is 0.1-0.2 ms of
//! work, called back to back from Python. A pool whose idle threads sleep (rayon's) wakes a helper every
//! step, and on this project's virtual machines that wake-up (a futex, an interrupt to a halted virtual
//! CPU) cost a third of the two cores' throughput: two threads gave 1.27 times one. Here an idle helper
//! waits spinning for [`SPIN`] after its last work, then sleeps; the caller always works beside the
//! helpers, and waits spinning for the last index in flight.
//!
//! One job at a time: a second caller while a job runs (another Python thread's batch) runs its indices
//! alone. A panic in `work` is raised again in the caller once every index has finished. The helpers
//! live as long as the process (they hold only the shared state): a child made by `fork` has none of them,
//! so whoever keeps a `Helpers` makes a new one there (the bindings key theirs by process id).

use std::any::Any;
use std::cell::UnsafeCell;
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// How long an idle helper keeps spinning for the next job before it sleeps: a few steps of the batch,
/// so that back-to-back steps never sleep, while a caller that does something else between steps (a
/// policy's forward pass) gets the core back soon.
pub const SPIN: Duration = Duration::from_micros(200);

/// The most indices of one job the helpers share (a job with more runs on the caller alone).
pub const MAX_INDICES: usize = (1 << INDEX_BITS) - 1;

/// The job's state word: its number (the high 32 bits), the end of the indices left and their start.
const INDEX_BITS: u32 = 16;
const INDEX_MASK: u64 = (1 << INDEX_BITS) - 1;

/// The work of the current job, lifetime erased: valid while the job's indices are not all done.
type Work = *const (dyn Fn(usize) + Sync);

struct Shared {
    /// `job << 32 | back << 16 | front`: which job, and its indices not yet taken, `front..back`.
    state: AtomicU64,
    /// Indices of the current job finished (run, or panicked).
    done: AtomicUsize,
    /// The current job's work; written by the caller before it publishes `state`, read by a thread only
    /// after it took an index of that job.
    work: UnsafeCell<Option<Work>>,
    /// The first panic of the current job.
    panic: Mutex<Option<Box<dyn Any + Send>>>,
    /// Helpers asleep, and what wakes them.
    sleeping: AtomicU32,
    bed: Mutex<()>,
    wake: Condvar,
    /// One job at a time.
    caller: Mutex<()>,
    /// The helpers are to end (their `Helpers` was dropped).
    closed: AtomicBool,
}

// SAFETY: `work` is written only by the caller holding `caller`, while no index of a job is outstanding
// (before it publishes the job, with a Release store of `state`); a thread reads it only after an Acquire
// CAS of `state` gave it an index of that job, and the caller does not return (nor write it again) before
// that index is counted in `done` (Release), which it reads with Acquire.
unsafe impl Sync for Shared {}
unsafe impl Send for Shared {}

/// A caller's helpers (see the crate's documentation).
pub struct Helpers {
    shared: Arc<Shared>,
    helpers: usize,
}

impl Helpers {
    /// `helpers` threads beside the caller, named `{name}-{i}`.
    pub fn new(helpers: usize, name: &str) -> std::io::Result<Self> {
        let shared = Arc::new(Shared {
            state: AtomicU64::new(0),
            done: AtomicUsize::new(0),
            work: UnsafeCell::new(None),
            panic: Mutex::new(None),
            sleeping: AtomicU32::new(0),
            bed: Mutex::new(()),
            wake: Condvar::new(),
            caller: Mutex::new(()),
            closed: AtomicBool::new(false),
        });
        let mut made = Self { shared, helpers: 0 };
        for i in 0..helpers {
            let s = Arc::clone(&made.shared);
            // On an error the threads made so far end with `made`.
            std::thread::Builder::new()
                .name(format!("{name}-{i}"))
                .spawn(move || helper(&s))?;
            made.helpers += 1;
        }
        Ok(made)
    }

    /// Threads beside the caller.
    pub fn helpers(&self) -> usize {
        self.helpers
    }

    /// Runs `work(i)` for each i in 0..n, each once, on the caller and the helpers; returns when all have
    /// finished, raising again the first panic of any.
    pub fn for_each(&self, n: usize, work: &(dyn Fn(usize) + Sync)) {
        let s = &*self.shared;
        let guard = match s.caller.try_lock() {
            Ok(g) => Some(g),
            Err(std::sync::TryLockError::Poisoned(e)) => Some(e.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => None,
        };
        if n <= 1 || self.helpers == 0 || n > MAX_INDICES || guard.is_none() {
            (0..n).for_each(work);
            return;
        }
        // SAFETY: the lifetime is erased for the helpers; `work` outlives this call, and every index is
        // done before it returns (also when `work` panics), so no thread runs it after.
        let erased: Work = unsafe { std::mem::transmute::<&(dyn Fn(usize) + Sync), Work>(work) };
        // SAFETY: no index of the last job is outstanding (its caller waited for all), and we hold `caller`.
        unsafe { *s.work.get() = Some(erased) };
        s.done.store(0, Ordering::Relaxed);
        let job = (s.state.load(Ordering::Relaxed) >> 32).wrapping_add(1) & 0xffff_ffff;
        s.state
            .store(job << 32 | (n as u64) << INDEX_BITS, Ordering::SeqCst);
        if s.sleeping.load(Ordering::SeqCst) > 0 {
            let _bed = s.bed.lock().unwrap_or_else(|e| e.into_inner());
            s.wake.notify_all();
        }
        take(s, job, false);
        // The indices in flight on the helpers.
        let mut spins = 0u32;
        while s.done.load(Ordering::Acquire) < n {
            spins = spins.saturating_add(1);
            if spins < 1 << 14 {
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
        // SAFETY: all indices are done and we hold `caller`.
        unsafe { *s.work.get() = None };
        let panic = s.panic.lock().unwrap_or_else(|e| e.into_inner()).take();
        drop(guard);
        if let Some(p) = panic {
            resume_unwind(p);
        }
    }
}

impl Drop for Helpers {
    /// Ends the helpers (a sleeping one is woken).
    fn drop(&mut self) {
        let s = &*self.shared;
        s.closed.store(true, Ordering::SeqCst);
        let _bed = s.bed.lock().unwrap_or_else(|e| e.into_inner());
        s.wake.notify_all();
    }
}

/// Takes and runs indices of job `job` until none are left (or another job is current): the caller from
/// the front, the helpers from the back, so that each thread runs much the same indices step after step
/// and finds their data in its own core's cache.
fn take(s: &Shared, job: u64, from_back: bool) {
    let mut state = s.state.load(Ordering::Acquire);
    loop {
        let (current, back, front) = (
            state >> 32,
            (state >> INDEX_BITS) & INDEX_MASK,
            state & INDEX_MASK,
        );
        if current != job || front >= back {
            return;
        }
        let (index, next) = if from_back {
            (back - 1, state - (1 << INDEX_BITS))
        } else {
            (front, state + 1)
        };
        match s
            .state
            .compare_exchange_weak(state, next, Ordering::Acquire, Ordering::Acquire)
        {
            Ok(_) => {
                // SAFETY: we hold `index` of `job`, so its caller waits for us and `work` is its.
                let work = unsafe { (*s.work.get()).expect("a job's work") };
                // SAFETY: as above, the work outlives the index.
                let r = catch_unwind(AssertUnwindSafe(|| unsafe { (*work)(index as usize) }));
                if let Err(p) = r {
                    let mut first = s.panic.lock().unwrap_or_else(|e| e.into_inner());
                    if first.is_none() {
                        *first = Some(p);
                    } else {
                        // Not dropped: a payload whose drop panics would end this thread before the
                        // index is counted, and its caller would wait for ever.
                        std::mem::forget(p);
                    }
                }
                s.done.fetch_add(1, Ordering::Release);
                state = s.state.load(Ordering::Acquire);
            }
            Err(now) => state = now,
        }
    }
}

/// A helper: waits for a new job (spinning for [`SPIN`], then asleep), takes its indices, again, until
/// its `Helpers` is dropped.
fn helper(s: &Shared) {
    let mut seen = s.state.load(Ordering::Acquire) >> 32;
    while !s.closed.load(Ordering::Relaxed) {
        let since = Instant::now();
        let mut spins = 0u32;
        let job = loop {
            let job = s.state.load(Ordering::Acquire) >> 32;
            if job != seen {
                break job;
            }
            if s.closed.load(Ordering::Relaxed) {
                return;
            }
            spins = spins.wrapping_add(1);
            if !spins.is_multiple_of(64) {
                std::hint::spin_loop();
                continue;
            }
            if since.elapsed() < SPIN {
                // A thread that waits for this core (more threads than cores) gets it.
                std::thread::yield_now();
                continue;
            }
            // Asleep until the caller publishes a job: counted first, then the job checked again under
            // the lock the caller takes to notify (so a job published in between is seen, or wakes us).
            let mut bed = s.bed.lock().unwrap_or_else(|e| e.into_inner());
            s.sleeping.fetch_add(1, Ordering::SeqCst);
            while s.state.load(Ordering::SeqCst) >> 32 == seen && !s.closed.load(Ordering::SeqCst) {
                bed = s.wake.wait(bed).unwrap_or_else(|e| e.into_inner());
            }
            s.sleeping.fetch_sub(1, Ordering::SeqCst);
            drop(bed);
        };
        seen = job;
        take(s, job, true);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU32;

    /// Each index once, for job sizes around the chunking a batch uses, on 1-3 helpers, job after job.
    #[test]
    fn every_index_runs_once() {
        for helpers in 1..=3 {
            let h = Helpers::new(helpers, "test").expect("threads");
            assert_eq!(h.helpers(), helpers);
            for n in [0, 1, 2, 3, 8, 17, 256, 1000] {
                let runs: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(0)).collect();
                h.for_each(n, &|i| {
                    runs[i].fetch_add(1, Ordering::Relaxed);
                });
                let counts: Vec<u32> = runs.iter().map(|r| r.load(Ordering::Relaxed)).collect();
                assert!(
                    counts.iter().all(|&c| c == 1),
                    "{helpers} helpers, n = {n}: {counts:?}"
                );
            }
        }
    }

    /// The helpers take indices too (the work is shared), and indices written by them are seen by the
    /// caller when `for_each` returns.
    #[test]
    fn helpers_share_the_work_and_their_writes_are_seen() {
        let h = Helpers::new(1, "test").expect("threads");
        let caller = std::thread::current().id();
        let mut on_a_helper = 0;
        // Under full load the helper may get its core late: jobs until it took some (bounded).
        let since = Instant::now();
        while on_a_helper == 0 && since.elapsed() < Duration::from_secs(20) {
            let n = 64;
            let out: Vec<Mutex<Option<(u64, std::thread::ThreadId)>>> =
                (0..n).map(|_| Mutex::new(None)).collect();
            h.for_each(n, &|i| {
                // Enough work that the helper, awake, takes some of the indices.
                let mut x = i as u64;
                for _ in 0..2000 {
                    x = x
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                }
                *out[i].lock().unwrap() = Some((x, std::thread::current().id()));
            });
            for (i, o) in out.iter().enumerate() {
                let (x, who) = o.lock().unwrap().expect("every index written");
                let mut want = i as u64;
                for _ in 0..2000 {
                    want = want
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                }
                assert_eq!(x, want);
                on_a_helper += usize::from(who != caller);
            }
        }
        assert!(
            on_a_helper > 0,
            "no index ran on the helper in 20 s of jobs"
        );
    }

    /// A job while the helpers sleep (idle longer than SPIN) wakes them: they take some of its indices
    /// (bounded by 20 s, for a loaded machine), and every job completes.
    #[test]
    fn a_job_after_the_helpers_slept_wakes_them() {
        let h = Helpers::new(2, "test").expect("threads");
        let caller = std::thread::current().id();
        let since = Instant::now();
        let mut woken = false;
        while !woken && since.elapsed() < Duration::from_secs(20) {
            // Both helpers asleep (on a loaded machine they may get their core late).
            while h.shared.sleeping.load(Ordering::SeqCst) < 2
                && since.elapsed() < Duration::from_secs(20)
            {
                std::thread::sleep(SPIN);
            }
            let sum = AtomicUsize::new(0);
            let helped = AtomicUsize::new(0);
            h.for_each(64, &|i| {
                // About 50 us an index: time for a sleeping helper to wake and take some.
                let t = Instant::now();
                while t.elapsed() < Duration::from_micros(50) {
                    std::hint::spin_loop();
                }
                sum.fetch_add(i, Ordering::Relaxed);
                helped.fetch_add(
                    usize::from(std::thread::current().id() != caller),
                    Ordering::Relaxed,
                );
            });
            assert_eq!(sum.load(Ordering::Relaxed), 2016);
            woken = helped.load(Ordering::Relaxed) > 0;
        }
        assert!(
            woken,
            "no helper took an index after sleeping, in 20 s of jobs"
        );
    }

    /// Dropping the helpers ends their threads (each held the shared state).
    #[test]
    fn dropped_helpers_end_their_threads() {
        let h = Helpers::new(3, "test").expect("threads");
        h.for_each(10, &|_| {});
        let shared = Arc::downgrade(&h.shared);
        drop(h);
        let since = Instant::now();
        while shared.strong_count() > 0 && since.elapsed() < Duration::from_secs(20) {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(
            shared.strong_count(),
            0,
            "helper threads still hold the shared state"
        );
    }

    /// A panic in the work is raised in the caller after every other index finished, and the helpers
    /// serve the next job.
    #[test]
    fn a_panic_is_raised_in_the_caller_and_the_helpers_go_on() {
        let h = Helpers::new(1, "test").expect("threads");
        let ran = AtomicUsize::new(0);
        let r = catch_unwind(AssertUnwindSafe(|| {
            h.for_each(50, &|i| {
                if i == 7 {
                    panic!("index seven");
                }
                ran.fetch_add(1, Ordering::Relaxed);
            })
        }));
        let msg = r.expect_err("the panic is raised");
        assert_eq!(msg.downcast_ref::<&str>(), Some(&"index seven"));
        assert_eq!(ran.load(Ordering::Relaxed), 49);
        let sum = AtomicUsize::new(0);
        h.for_each(10, &|i| {
            sum.fetch_add(i, Ordering::Relaxed);
        });
        assert_eq!(sum.load(Ordering::Relaxed), 45);
    }

    /// Two callers at once (two Python threads' batches): both jobs complete, each index once.
    #[test]
    fn two_callers_at_once_both_complete() {
        let h = Helpers::new(1, "test").expect("threads");
        std::thread::scope(|scope| {
            for t in 0..2 {
                let h = &h;
                scope.spawn(move || {
                    for round in 0..300 {
                        let n = 16 + (round + t) % 7;
                        let runs: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(0)).collect();
                        h.for_each(n, &|i| {
                            runs[i].fetch_add(1, Ordering::Relaxed);
                        });
                        assert!(runs.iter().all(|r| r.load(Ordering::Relaxed) == 1));
                    }
                });
            }
        });
    }

    /// More indices than the state word holds run on the caller alone, each once.
    #[test]
    fn more_indices_than_shared_run_on_the_caller() {
        let h = Helpers::new(1, "test").expect("threads");
        let n = MAX_INDICES + 5;
        let runs: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(0)).collect();
        h.for_each(n, &|i| {
            runs[i].fetch_add(1, Ordering::Relaxed);
        });
        assert!(runs.iter().all(|r| r.load(Ordering::Relaxed) == 1));
    }
}
