//! The parent side of `grasp-gen render`: plans sequences, hands them to N
//! worker processes, restarts crashed workers and retries their sequences a
//! bounded number of times, recycles workers every `recycle_every`
//! sequences, shows progress, and stops cleanly when `stop` is raised.
//!
//! * `resume`: what a non-empty output folder may hold, and what is redone.
//! * `pool`: the parent's event loop and progress.
//! * `slot`: one worker slot's thread; `worker_proc`: its process.
//! * `outputs`: meshes, records and the manifest.
//! * `shared`: what they all share (a job, a slot's events, the summary).

mod outputs;
mod pool;
mod resume;
mod shared;
mod slot;
mod worker_proc;

pub use shared::RenderSummary;

use super::source::RenderSource;
use super::{RenderConfig, Shard};
use crate::dataset::lock;
use crate::dataset::{assign_folders, Assigned, DatasetDir};
use crate::render::error::{RenderError, Result};
use grasp_support::atomic::write_atomic;
use outputs::{finish_manifest, write_meshes};
use pool::run_pool;
use resume::{refuse_other_sequences, unfinished_jobs};
use shared::Shared;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Instant;

#[derive(Debug, Clone)]
pub struct RenderOptions {
    pub out: PathBuf,
    pub workers: usize,
    pub shard: Shard,
    /// Skip finished sequences instead of refusing a non-empty dataset.
    pub resume: bool,
    /// The `grasp-gen` executable to run workers from.
    pub worker_exe: PathBuf,
    pub progress: bool,
    /// Raised by the Ctrl-C handler: stop handing out work, kill workers.
    pub stop: Arc<AtomicBool>,
    /// Extra environment variables of the worker processes.
    pub worker_env: Vec<(String, String)>,
    /// Take over the output lock of a holder on another machine once its
    /// heartbeat has stopped (see [`crate::dataset::lock`]).
    pub break_lock: bool,
}

/// Renders every unfinished sequence of `shard` into `opts.out`.
pub fn render(
    source: Arc<dyn RenderSource>,
    config: &RenderConfig,
    opts: &RenderOptions,
) -> Result<RenderSummary> {
    config.validate()?;
    let start = Instant::now();
    let dataset = DatasetDir::create(&opts.out)?;
    let lock = lock::acquire(&dataset.work_dir(), opts.shard, "render", opts.break_lock)?;
    let keys = source.keys()?;
    let in_shard: Vec<Assigned> = assign_folders(&keys)
        .into_iter()
        .filter(|a| opts.shard.contains(a.position))
        .collect();
    let finished: Vec<bool> = in_shard
        .iter()
        .map(|a| dataset.is_finished(&a.rel_dir))
        .collect();
    let finished_count = finished.iter().filter(|f| **f).count();
    refuse_other_sequences(source.as_ref(), &dataset, &in_shard, &finished, config)?;
    if finished_count > 0 && !opts.resume {
        return Err(RenderError::AlreadyRendered {
            out: opts.out.clone(),
            finished: finished_count,
        });
    }
    dataset.clean_partials(opts.shard)?;
    let mut summary = RenderSummary {
        in_shard: in_shard.len(),
        ..Default::default()
    };
    let todo = unfinished_jobs(&dataset, &in_shard, &finished, &mut summary);
    let total = todo.len();
    if total > 0 {
        let meshes = write_meshes(source.as_ref(), &dataset, &todo)?;
        // Kept for re-renders and the naive benchmark script.
        let scene_json =
            serde_json::to_vec_pretty(&source.scene()).map_err(|source| RenderError::Json {
                what: "the scene geometry",
                source,
            })?;
        write_atomic(&dataset.work_dir().join("scene.json"), &scene_json)?;
        let workers = opts.workers.clamp(1, total);
        let ctx = Arc::new(Shared {
            geometry: source.scene(),
            source,
            dataset: dataset.clone(),
            settings: config.blender_settings(),
            meshes,
            exe: opts.worker_exe.clone(),
            worker_env: opts.worker_env.clone(),
            recycle_every: config.recycle_every,
            max_retries: config.max_retries,
            part_pass: config.passes.contains(&super::Pass::Part),
            queue: Mutex::new(todo),
            stop: opts.stop.clone(),
            children: Mutex::new(vec![None; workers]),
            log_prefix: match opts.shard == Shard::ALL {
                true => String::new(),
                false => format!("shard-{}-of-{}-", opts.shard.index, opts.shard.count),
            },
        });
        summary.interrupted = run_pool(&ctx, workers, total, opts.progress, &lock, &mut summary)?;
    }
    if lock.lost() {
        // The folder is another run's now: leave its partials and manifest.
        summary.seconds = start.elapsed().as_secs_f64();
        return Ok(summary);
    }
    dataset.clean_partials(opts.shard)?;
    finish_manifest(&dataset, opts.shard, lock)?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}
