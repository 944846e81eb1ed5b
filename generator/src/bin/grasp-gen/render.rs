//! The `render` and hidden `worker` subcommands.

use anyhow::{bail, Context, Result};
use clap::Args;
use generator::config::ConfigArgs;
use generator::render::{planner_source, render, RenderOptions, Shard};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

#[derive(Debug, Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Dataset root to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Worker processes (default: [render] workers).
    #[arg(long)]
    pub workers: Option<usize>,
    /// Render only shard K of N (0-based), e.g. 3/16 for array task 3.
    #[arg(long, default_value = "0/1")]
    pub shard: Shard,
    /// Keep finished sequences and render the rest.
    #[arg(long)]
    pub resume: bool,
    /// No progress bar (logs and batch jobs).
    #[arg(long)]
    pub no_progress: bool,
    /// Take over the output folder's lock from a run on another machine
    /// once its heartbeat has stopped (waits 3 heartbeats of 10 s). A dead
    /// run on this machine, or an earlier run of the same Slurm job, is
    /// detected without it; a live run is never overridden.
    #[arg(long)]
    pub break_lock: bool,
}

pub fn run_render(args: &RenderArgs) -> Result<()> {
    let config = args.config.load()?;
    config.appearance.validate()?;
    let mut render_cfg = config.render.clone();
    if let Some(w) = args.workers {
        render_cfg.workers = w;
    }
    let source = planner_source::from_config(&config)?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            eprintln!("second Ctrl-C: exiting now");
            std::process::exit(130);
        }
        eprintln!("Ctrl-C: stopping after cleaning up (press again to exit at once)");
    })
    .context("cannot install the Ctrl-C handler")?;
    let opts = RenderOptions {
        out: args.out.clone(),
        workers: render_cfg.workers,
        shard: args.shard,
        resume: args.resume,
        worker_exe: std::env::current_exe().context("cannot find the grasp-gen executable")?,
        progress: !args.no_progress,
        stop,
        worker_env: Vec::new(),
        break_lock: args.break_lock,
    };
    let s = render(source, &render_cfg, &opts)?;
    println!(
        "shard {}: {} sequences, {} already done, {} rendered{} ({} frames, {:.2} frames/s, {} retries) in {:.1} s",
        args.shard,
        s.in_shard,
        s.skipped,
        s.rendered,
        match s.redone {
            0 => String::new(),
            n => format!(" ({n} of them damaged or incomplete before)"),
        },
        s.frames,
        s.frames_per_second(),
        s.retries,
        s.seconds
    );
    if !s.devices.is_empty() {
        let devices: Vec<&str> = s.devices.iter().map(String::as_str).collect();
        println!("rendered on: {}", devices.join(", "));
    }
    if s.peak_worker_rss_kib > 0 {
        println!(
            "peak worker memory (RSS): {:.0} MiB",
            s.peak_worker_rss_kib as f64 / 1024.0
        );
    }
    if let Some(why) = &s.fatal {
        bail!(
            "stopped: {why}\n{} finished sequences are kept; fix the cause and run again with \
             --resume",
            s.skipped + s.rendered
        );
    }
    if s.interrupted {
        bail!("interrupted; run again with --resume to finish");
    }
    if !s.failed.is_empty() {
        for (id, e) in &s.failed {
            eprintln!("failed: {id}: {e}");
        }
        bail!("{} sequences failed", s.failed.len());
    }
    Ok(())
}

pub fn run_worker() -> Result<()> {
    Ok(generator::render::worker::run()?)
}
