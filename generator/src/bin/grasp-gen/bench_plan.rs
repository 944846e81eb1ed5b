//! `grasp-gen bench-plan` (hidden): the numbers of BENCHMARKS.md's "Reach
//! planning" section, printed as Markdown. A benchmark of the binary, kept
//! out of the library.

use crate::plan::{load_inputs, plan_all};
use anyhow::Result;
use generator::plan::trajectory::{frame_tau, min_jerk, min_jerk_velocity};
use generator::plan::{sequence_keys, Planner};
use grasp_schema::Condition;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub config: generator::config::ConfigArgs,
    #[arg(long)]
    pub catalog: Option<PathBuf>,
    /// Sequences per pair and condition (the authors' 50 gives 1550 per condition).
    #[arg(long, default_value_t = 50)]
    pub sequences_per_pair: u32,
    /// Conditions to time (default: all five).
    #[arg(long, value_delimiter = ',')]
    pub conditions: Vec<Condition>,
    /// Skip the one-candidate-per-call comparison run.
    #[arg(long)]
    pub no_unbatched: bool,
}

pub fn run(args: &BenchArgs) -> Result<()> {
    endpoint_table();
    let (mut config, catalog) = load_inputs(&args.config, args.catalog.as_deref())?;
    config.dataset.sequences_per_pair = args.sequences_per_pair;
    let conditions = if args.conditions.is_empty() {
        Condition::ALL.to_vec()
    } else {
        args.conditions.clone()
    };
    let started = Instant::now();
    let planner = Planner::new(&config, &catalog)?;
    println!(
        "\nPlanner set-up (meshes into trimesh/Embree): {:.2} s\n",
        started.elapsed().as_secs_f64()
    );
    println!("| condition | sequences | total (s) | per sequence (ms) | mean attempts | tolerance used |");
    println!("|---|---|---|---|---|---|");
    for &c in &conditions {
        config.dataset.conditions = vec![c];
        let keys = sequence_keys(&config, &catalog);
        let t = Instant::now();
        let plans = plan_all(&planner, &keys, true)?;
        let secs = t.elapsed().as_secs_f64();
        let attempts: f64 = plans
            .iter()
            .filter_map(|p| p.sampled.get("attempts")?.as_f64())
            .sum::<f64>()
            / plans.len() as f64;
        let tol = plans
            .iter()
            .filter(|p| {
                p.sampled.get("mesh_tolerance_used") == Some(&serde_json::Value::Bool(true))
            })
            .count();
        println!(
            "| {c} | {} | {secs:.2} | {:.2} | {attempts:.2} | {tol} |",
            plans.len(),
            1e3 * secs / plans.len() as f64
        );
    }
    if !args.no_unbatched {
        config.dataset.conditions = vec![Condition::Default];
        let keys = sequence_keys(&config, &catalog);
        let mut timings = Vec::new();
        for batch in [1usize, config.plan.validity.batch_size] {
            let mut c = config.clone();
            c.plan.validity.batch_size = batch;
            let planner = Planner::new(&c, &catalog)?;
            let t = Instant::now();
            plan_all(&planner, &keys, true)?;
            timings.push((batch, t.elapsed().as_secs_f64()));
        }
        println!(
            "\n| default condition, {} sequences | total (s) |",
            keys.len()
        );
        println!("|---|---|");
        for (b, s) in &timings {
            println!("| up to {b} candidates per trimesh call | {s:.2} |");
        }
        println!(
            "| ratio (1 / batched) | {:.2} |",
            timings[0].1 / timings[1].1
        );
    }
    Ok(())
}

/// Endpoint error of a 0.56 m reach after n frames: the closed form versus
/// per-frame accumulation in f32, as a game-engine update loop does.
fn endpoint_table() {
    let start = [-0.45_f64, 0.12, 1.05];
    let end = [0.05_f64, -0.03, 0.80];
    println!("| frames | closed form f64 (m) | closed form f32 (m) | f32 += per-frame delta (m) | f32 += velocity * dt (m) |");
    println!("|---|---|---|---|---|");
    for n in [10usize, 100, 1_000, 10_000, 100_000] {
        let (mut acc_delta, mut acc_vel) = ([0f32; 3], [0f32; 3]);
        for k in 0..3 {
            acc_delta[k] = start[k] as f32;
            acc_vel[k] = start[k] as f32;
        }
        let dt = 1.0 / (n - 1) as f32;
        for i in 1..n {
            let (t0, t1) = (frame_tau(i - 1, n), frame_tau(i, n));
            for k in 0..3 {
                let d = (end[k] - start[k]) as f32;
                acc_delta[k] += d * (min_jerk(t1) as f32 - min_jerk(t0) as f32);
                // Midpoint velocity: the best an update loop with dt can do.
                acc_vel[k] += d * min_jerk_velocity((t0 + t1) / 2.0) as f32 * dt;
            }
        }
        let closed64: Vec<f64> = (0..3)
            .map(|k| start[k] + (end[k] - start[k]) * min_jerk(frame_tau(n - 1, n)))
            .collect();
        let closed32: Vec<f32> = (0..3)
            .map(|k| start[k] as f32 + (end[k] - start[k]) as f32 * min_jerk(1.0) as f32)
            .collect();
        let err = |p: &[f64]| (0..3).map(|k| (p[k] - end[k]).powi(2)).sum::<f64>().sqrt();
        let widen = |p: &[f32]| p.iter().map(|x| f64::from(*x)).collect::<Vec<_>>();
        println!(
            "| {n} | {:.1e} | {:.1e} | {:.1e} | {:.1e} |",
            err(&closed64),
            err(&widen(&closed32)),
            err(&widen(&acc_delta)),
            err(&widen(&acc_vel))
        );
    }
}
