//! How much of `hannes-run bench`'s tail is the host's: the same statistics
//! for work that has no tail of its own.
//!
//! 1. **Gaps.** Threads that only read the clock in a loop, one busy thread
//!    and then two: every jump of more than 0.1 ms between two reads is time
//!    the thread did not run (another process, the kernel, or on a virtual
//!    machine the hypervisor taking the virtual CPU away).
//! 2. **A fixed workload.** The same arithmetic every repetition, lasting
//!    `--ms` on one thread, and twice as much split in two halves on two
//!    threads and joined, as a parallel kernel is (again about `--ms`): its
//!    p50 and p99 per repetition. Its p99 above its p50 is the floor that
//!    any frame of that length on that many threads meets on this host.
//!
//!   cargo run --release -p runtime --example host_jitter -- --ms 6 --reps 300
//!
//! Prints one JSON object.

use std::time::{Duration, Instant};

use clap::Parser;
use serde_json::json;

#[derive(Parser)]
struct Args {
    /// Length of the fixed workload, in milliseconds.
    #[arg(long, default_value_t = 6.0)]
    ms: f64,
    /// Timed repetitions per thread count.
    #[arg(long, default_value_t = 300)]
    reps: usize,
    /// Seconds each gap probe runs.
    #[arg(long, default_value_t = 5.0)]
    seconds: f64,
}

/// Gaps in a thread's reading of the clock longer than this are counted.
const GAP: Duration = Duration::from_micros(100);

fn main() {
    let args = Args::parse();
    let gaps: Vec<_> = [1, 2]
        .into_iter()
        .map(|threads| gap_probe(threads, args.seconds))
        .collect();
    let rounds = calibrate(args.ms);
    let workload: Vec<_> = [1, 2]
        .into_iter()
        .map(|threads| fixed_workload(threads, rounds * threads, args.reps))
        .collect();
    let report = json!({
        "gaps": gaps,
        "fixed_workload": { "ms": args.ms, "runs": workload },
    });
    println!("{report}");
}

/// `threads` threads spinning on the clock for `seconds`: per thread, the
/// gaps over 0.1 ms, those of 1 ms or more, their total and the longest.
fn gap_probe(threads: usize, seconds: f64) -> serde_json::Value {
    let per_thread: Vec<Vec<f64>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|_| s.spawn(move || gaps_while_spinning(seconds)))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let rows: Vec<_> = per_thread
        .iter()
        .map(|gaps| {
            let long = gaps.iter().filter(|&&g| g >= 1.0).count();
            json!({
                "gaps": gaps.len(),
                "gaps_of_1ms_or_more": long,
                "per_second_of_1ms_or_more": long as f64 / seconds,
                "total_ms": gaps.iter().sum::<f64>(),
                "longest_ms": gaps.iter().copied().fold(0.0, f64::max),
            })
        })
        .collect();
    json!({ "busy_threads": threads, "seconds": seconds, "threads": rows })
}

/// Reads the clock for `seconds`; the gaps over [`GAP`], in milliseconds.
fn gaps_while_spinning(seconds: f64) -> Vec<f64> {
    let start = Instant::now();
    let end = Duration::from_secs_f64(seconds);
    let mut last = Duration::ZERO;
    let mut gaps = Vec::new();
    loop {
        let now = start.elapsed();
        if now - last > GAP {
            gaps.push((now - last).as_secs_f64() * 1e3);
        }
        last = now;
        if now > end {
            return gaps;
        }
    }
}

/// Elements of the workload's buffer: 256 KB of f32, in L2 on any x86 core.
const LEN: usize = 1 << 16;

/// `rounds` passes of a dependent square root over `data`: memory-light
/// arithmetic whose time does not depend on the data.
fn work(data: &mut [f32], rounds: usize) {
    for _ in 0..rounds {
        for x in data.iter_mut() {
            *x = (*x * 1.0001 + 0.5).sqrt();
        }
    }
    std::hint::black_box(data);
}

/// Passes over the whole buffer that take `ms` on one thread (the median of
/// a few tries).
fn calibrate(ms: f64) -> usize {
    let mut data = vec![1.0f32; LEN];
    let probe = 20;
    let mut tries: Vec<f64> = (0..7)
        .map(|_| {
            let t = Instant::now();
            work(&mut data, probe);
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    tries.sort_by(f64::total_cmp);
    ((ms / tries[tries.len() / 2]) * probe as f64)
        .round()
        .max(1.0) as usize
}

/// `rounds` passes `reps` times on `threads` threads (the buffer split in
/// equal parts, each thread its part, joined): p50, p99 and max in ms.
fn fixed_workload(threads: usize, rounds: usize, reps: usize) -> serde_json::Value {
    let mut data = vec![1.0f32; LEN];
    let part = LEN / threads;
    let mut ms: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let t = Instant::now();
            std::thread::scope(|s| {
                let mut parts = data.chunks_mut(part);
                let mine = parts.next().unwrap();
                for other in parts {
                    s.spawn(move || work(other, rounds));
                }
                work(mine, rounds);
            });
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    let rank = |q: f64| ms[((q * ms.len() as f64).ceil() as usize).clamp(1, ms.len()) - 1];
    json!({
        "threads": threads,
        "reps": ms.len(),
        "p50_ms": rank(0.5),
        "p99_ms": rank(0.99),
        "max_ms": ms[ms.len() - 1],
    })
}
