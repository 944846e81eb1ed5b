//! The threads the blocked kernels split a layer over: the caller and
//! helper threads that spin between layers instead of sleeping.
//!
//! An image is ~50 layers of ~20-100 us each. On rayon's pool a worker
//! that finds no job soon sleeps, and each layer wakes it again; in a
//! virtual machine waking a halted vCPU costs tens of microseconds, more
//! after the camera's ~30 ms idle (on rayon alone, one thread ran a frame
//! at 30 frames/s faster than two). The team's helpers wait for the next
//! layer spinning for [`SPIN`] (yielding to any other runnable thread),
//! so an image wakes them once: the network at 30 frames/s took about 40 %
//! less at p50 and 35 % less at p99, back to back level with rayon
//! (BENCHMARKS.md). Jobs are claimed in shrinking chunks from one counter
//! (guided scheduling: few claims, balanced ends); the caller runs
//! whatever is unclaimed.

use crossbeam_utils::CachePadded;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// How long a helper spins for the next layer before it sleeps: longer
/// than the gaps between an image's layers, short against the camera's
/// period.
const SPIN: Duration = Duration::from_micros(200);

/// Polls between yields of a spinning helper (~50 us): every 64 cost the
/// network 5-10 % back to back, never yielding raised its p99 by a third
/// or more, 1024 and 4096 were level with rayon back to back
/// (BENCHMARKS.md).
const SPINS_PER_YIELD: usize = 1024;

/// `(generation, jobs, next)` packed in one word, so that a claim names
/// the call it belongs to.
const NEXT_BITS: u32 = 24;
const JOBS_BITS: u32 = 16;
const NEXT_MASK: u64 = (1 << NEXT_BITS) - 1;
const JOBS_MASK: u64 = (1 << JOBS_BITS) - 1;
const GENERATION_MASK: u64 = (1 << (64 - NEXT_BITS - JOBS_BITS)) - 1;

fn unpack(word: u64) -> (u64, usize, usize) {
    let next = (word & NEXT_MASK) as usize;
    let jobs = ((word >> NEXT_BITS) & JOBS_MASK) as usize;
    (word >> (NEXT_BITS + JOBS_BITS), jobs, next)
}

fn pack(generation: u64, jobs: usize, next: usize) -> u64 {
    (generation << (NEXT_BITS + JOBS_BITS)) | ((jobs as u64) << NEXT_BITS) | next as u64
}

/// A call's job, its lifetime erased: valid while its caller waits.
#[derive(Clone, Copy)]
struct Task(*const (dyn Fn(usize) + Sync));
// SAFETY: the closure is Sync and outlives every use (`Team::run` returns
// only after every claimed job has finished).
unsafe impl Send for Task {}

#[derive(Default)]
struct Shared {
    /// Alone on its cache line: every thread polls it, and it must not
    /// share one with the counter the caller polls.
    claims: CachePadded<AtomicU64>,
    /// Jobs of the current call finished.
    done: CachePadded<AtomicUsize>,
    task: Mutex<Option<Task>>,
    panicked: AtomicBool,
    sleepers: AtomicUsize,
    wake: Condvar,
    asleep: Mutex<()>,
}

pub(super) struct Team {
    shared: &'static Shared,
    /// One caller at a time; another runs its jobs on rayon's pool.
    caller: Mutex<()>,
    threads: usize,
}

impl Team {
    /// The process's team: as many threads as rayon's pool, the caller's
    /// included.
    pub fn global() -> &'static Team {
        static TEAM: OnceLock<Team> = OnceLock::new();
        TEAM.get_or_init(|| Team::new(rayon::current_num_threads().saturating_sub(1)))
    }

    fn new(helpers: usize) -> Team {
        let shared: &'static Shared = Box::leak(Box::default());
        // a helper the OS refuses only leaves its chunks to the others
        // (the helpers size theirs for the threads asked for)
        let started = (0..helpers)
            .take_while(|i| {
                let spawned = std::thread::Builder::new()
                    .name(format!("blocked-helper-{i}"))
                    .spawn(move || helper(shared, helpers + 1));
                if let Err(e) = &spawned {
                    tracing::warn!("kernel helper thread {i} not started ({e}): fewer threads");
                }
                spawned.is_ok()
            })
            .count();
        Team {
            shared,
            caller: Mutex::new(()),
            threads: started + 1,
        }
    }

    /// Runs `f(0..jobs)`, each job once; returns when all have finished.
    pub fn run(&self, jobs: usize, f: &(dyn Fn(usize) + Sync)) {
        let guard = match self.caller.try_lock() {
            Ok(g) if self.threads > 1 && jobs as u64 <= JOBS_MASK => g,
            _ => {
                use rayon::prelude::*;
                return (0..jobs).into_par_iter().for_each(f);
            }
        };
        let s = self.shared;
        // SAFETY (of the erased lifetime): this call returns only after
        // `done` counts every job below `jobs`, and a claim past `jobs`
        // never reads the task.
        let task: *const (dyn Fn(usize) + Sync) = f;
        let task: *const (dyn Fn(usize) + Sync + 'static) = unsafe { std::mem::transmute(task) };
        *lock(&s.task) = Some(Task(task));
        s.done.store(0, Ordering::Relaxed);
        let generation = (unpack(s.claims.load(Ordering::Relaxed)).0 + 1) & GENERATION_MASK;
        // SeqCst with the sleepers check: a helper going to sleep either
        // sees this call or is counted and woken
        s.claims.store(pack(generation, jobs, 0), Ordering::SeqCst);
        if s.sleepers.load(Ordering::SeqCst) > 0 {
            let _asleep = lock(&s.asleep);
            s.wake.notify_all();
        }
        // a panicking job is caught and counted done like any, so that no
        // helper still runs a job of this call when it unwinds
        claim(s, generation, self.threads, &|j| guarded(s, f, j));
        while s.done.load(Ordering::Acquire) < jobs {
            std::hint::spin_loop();
        }
        *lock(&s.task) = None;
        drop(guard);
        if s.panicked.swap(false, Ordering::Relaxed) {
            panic!("a blocked kernel job panicked");
        }
    }
}

/// `f(j)`, a panic recorded for the caller to raise.
fn guarded(s: &Shared, f: &(dyn Fn(usize) + Sync), j: usize) {
    if std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(j))).is_err() {
        s.panicked.store(true, Ordering::Relaxed);
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A helper thread: runs chunks of each call, spins [`SPIN`] for the next
/// one, then sleeps until a call wakes it.
fn helper(s: &Shared, threads: usize) {
    let mut seen = unpack(s.claims.load(Ordering::Acquire)).0;
    loop {
        seen = wait_for_call(s, seen);
        // the task of the call whose claims this helper reads: a claim is
        // made in a call's generation, and the task stays until its jobs
        // are done, so a chunk claimed below always belongs to this task
        let Some(Task(task)) = *lock(&s.task) else {
            continue;
        };
        // SAFETY: used only for jobs claimed in this generation, while its
        // caller waits for them.
        let f = unsafe { &*task };
        claim(s, seen, threads, &|j| guarded(s, f, j));
    }
}

/// Claims chunks of call `generation`'s jobs until none are left (or a
/// later call began), running each; a chunk is the unclaimed jobs over
/// twice the threads.
fn claim(s: &Shared, generation: u64, threads: usize, f: &dyn Fn(usize)) {
    let mut word = s.claims.load(Ordering::Acquire);
    loop {
        let (g, jobs, next) = unpack(word);
        if g != generation || next >= jobs {
            return;
        }
        let chunk = (jobs - next).div_ceil(2 * threads);
        let claimed = pack(g, jobs, next + chunk);
        match s
            .claims
            .compare_exchange_weak(word, claimed, Ordering::Acquire, Ordering::Acquire)
        {
            Ok(_) => {
                for j in next..next + chunk {
                    f(j);
                }
                s.done.fetch_add(chunk, Ordering::Release);
                word = claimed;
            }
            Err(now) => word = now,
        }
    }
}

/// The generation of the first call after `seen`: spinning, then asleep.
fn wait_for_call(s: &Shared, seen: u64) -> u64 {
    let current = || unpack(s.claims.load(Ordering::SeqCst)).0;
    let start = Instant::now();
    loop {
        for _ in 0..SPINS_PER_YIELD {
            let g = current();
            if g != seen {
                return g;
            }
            std::hint::spin_loop();
        }
        // a runnable thread of the frame (the caller between layers, a
        // rayon worker) must not wait behind this spin for a time slice
        std::thread::yield_now();
        if start.elapsed() > SPIN {
            break;
        }
    }
    let mut asleep = lock(&s.asleep);
    s.sleepers.fetch_add(1, Ordering::SeqCst);
    loop {
        let g = current();
        if g != seen {
            s.sleepers.fetch_sub(1, Ordering::SeqCst);
            return g;
        }
        asleep = s.wake.wait(asleep).unwrap_or_else(|p| p.into_inner());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counted(team: &Team, jobs: usize) -> bool {
        let counts: Vec<AtomicUsize> = (0..jobs).map(|_| AtomicUsize::new(0)).collect();
        team.run(jobs, &|j| {
            counts[j].fetch_add(1, Ordering::Relaxed);
        });
        counts.iter().all(|c| c.load(Ordering::Relaxed) == 1)
    }

    #[test]
    fn every_job_runs_once_across_many_calls() {
        let team = Team::new(2);
        for jobs in [0, 1, 2, 3, 31, 32, 1000] {
            for _ in 0..200 {
                assert!(counted(&team, jobs), "{jobs}");
            }
        }
    }

    #[test]
    fn sleeping_helpers_wake_for_the_next_call() {
        let team = Team::new(1);
        for _ in 0..5 {
            assert!(counted(&team, 8));
            std::thread::sleep(SPIN * 3);
        }
    }

    #[test]
    fn concurrent_callers_all_finish() {
        let team = Team::new(1);
        std::thread::scope(|scope| {
            for _ in 0..4 {
                scope.spawn(|| (0..100).for_each(|_| assert!(counted(&team, 16))));
            }
        });
    }

    #[test]
    fn a_panicking_job_panics_the_caller_after_the_others_finish() {
        let team = Team::new(1);
        let finished = AtomicUsize::new(0);
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            team.run(16, &|j| {
                assert_ne!(j, 5, "job 5 fails");
                finished.fetch_add(1, Ordering::Relaxed);
            })
        }));
        assert!(r.is_err());
        assert_eq!(finished.load(Ordering::Relaxed), 15);
        assert!(counted(&team, 16), "the team works on after a panic");
    }

    #[test]
    fn claims_pack_and_unpack() {
        assert_eq!(unpack(pack(5, 32, 7)), (5, 32, 7));
    }
}
