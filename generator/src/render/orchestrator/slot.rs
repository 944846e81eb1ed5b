//! One worker slot: a thread that takes jobs from the queue, plans each
//! into a render request, hands it to its worker process (started on
//! demand, recycled every `recycle_every` sequences) and reports back.

use super::shared::{Event, Job, Rendered, Shared};
use super::worker_proc::WorkerProc;
use crate::dataset::error::chain;
use crate::dataset::storage;
use crate::dataset::writer::frame_files;
use crate::dataset::DatasetDir;
use crate::render::error::{RenderError, Result};
use crate::render::protocol::{RenderRequest, Request, Response};
use grasp_schema::dataset::RenderCost;
use grasp_schema::SequencePlan;
use std::path::{Path, PathBuf};
use std::sync::mpsc::Sender;

/// A slot's worker process and how many sequences it has served since it
/// started.
struct SlotWorker<'a> {
    slot: usize,
    ctx: &'a Shared,
    tx: &'a Sender<Event>,
    log: PathBuf,
    proc: Option<WorkerProc>,
    served: usize,
}

/// One worker slot: takes jobs until the queue is empty or stop is raised.
pub(super) fn worker_slot(slot: usize, ctx: &Shared, tx: &Sender<Event>) {
    let mut worker = SlotWorker {
        slot,
        ctx,
        tx,
        log: ctx.worker_log(slot),
        proc: None,
        served: 0,
    };
    while !ctx.stopped() {
        let Some(job) = ctx
            .queue
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop_front()
        else {
            break;
        };
        let id = job.assigned.planned.key.id();
        let (plan, request) = match prepare(ctx, &job) {
            Ok(p) => p,
            Err(e) => {
                let _ = tx.send(Event::Failed {
                    id,
                    error: chain(&e),
                });
                continue;
            }
        };
        let partial = request.out_dir.clone();
        let files = request.frame_files.clone();
        let head_partial = request.head_out_dir.clone();
        let part_labels: Vec<String> = request.parts.iter().map(|p| p.name.clone()).collect();
        match worker.render(request) {
            Ok((peak_rss_kib, cost)) => {
                let _ = tx.send(Event::Rendered(Box::new(Rendered {
                    peak_rss_kib,
                    cost,
                    part_labels,
                    job,
                    plan,
                    partial,
                    files,
                })));
                worker.served_one();
            }
            Err(e) => {
                let _ = std::fs::remove_dir_all(&partial);
                if let Some(h) = &head_partial {
                    let _ = std::fs::remove_dir_all(h);
                }
                if ctx.stopped() || !report_failure(ctx, tx, job, id, e) {
                    break;
                }
            }
        }
    }
    if let Some(p) = worker.proc.take() {
        p.quit();
    }
}

impl SlotWorker<'_> {
    /// Renders one request, starting the worker process first if needed;
    /// a worker that died is forgotten so the next job starts a fresh one.
    fn render(&mut self, request: RenderRequest) -> Result<(u64, RenderCost)> {
        if self.proc.is_none() {
            let mut started = WorkerProc::spawn(self.slot, self.ctx)?;
            if let Some(note) = started.note.take() {
                let _ = self.tx.send(Event::Note(note));
            }
            self.proc = Some(started);
        }
        let p = self.proc.as_mut().expect("worker started above");
        match p.call(&Request::Render(Box::new(request)), &self.log) {
            Ok(Response::Done {
                peak_rss_kib,
                rss_kib,
                cost,
                ..
            }) => {
                // RUST_LOG=generator::render=debug traces worker memory.
                let (slot, served) = (self.slot, self.served);
                tracing::debug!(slot, served, rss_kib, peak_rss_kib, "worker memory");
                Ok((peak_rss_kib, cost))
            }
            Ok(Response::Error { message, .. }) => Err(RenderError::WorkerFailed { message }),
            Ok(other) => Err(RenderError::UnexpectedAnswer {
                answer: format!("{other:?}"),
            }),
            Err(e) => {
                self.proc = None;
                Err(e)
            }
        }
    }

    /// Counts a rendered sequence; recycles the worker process when it has
    /// served `recycle_every` (Blender's memory grows with every scene).
    fn served_one(&mut self) {
        self.served += 1;
        if self.served >= self.ctx.recycle_every {
            if let Some(p) = self.proc.take() {
                p.quit();
            }
            self.served = 0;
        }
    }
}

/// Reports a failed job: fatal (no worker can start, or a full disk fails
/// every sequence alike), retried while attempts remain, else failed.
/// False when the slot must stop.
fn report_failure(ctx: &Shared, tx: &Sender<Event>, job: Job, id: String, e: RenderError) -> bool {
    if matches!(e, RenderError::WorkerStart { fatal: true, .. }) {
        let error = chain(&e);
        let _ = tx.send(Event::Fatal { id, error });
        return false;
    }
    let full = match storage::is_storage_full(&e) {
        true => None,
        false => storage::probe(&ctx.dataset.work_dir().join("partial")),
    };
    if storage::is_storage_full(&e) || full.is_some() {
        let error = match full {
            Some(f) => format!("{}; {}", chain(&e), chain(&f)),
            None => chain(&e),
        };
        let _ = tx.send(Event::Fatal { id, error });
        return false;
    }
    let error = chain(&e);
    if job.attempt < ctx.max_retries {
        let _ = tx.send(Event::Retry { id, error });
        ctx.queue
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push_back(Job {
                attempt: job.attempt + 1,
                ..job
            });
    } else {
        let _ = tx.send(Event::Failed { id, error });
    }
    true
}

/// Plans a job and builds its render request.
fn prepare(ctx: &Shared, job: &Job) -> Result<(SequencePlan, RenderRequest)> {
    let key = &job.assigned.planned.key;
    let plan = ctx.source.plan(key).map_err(|e| RenderError::Planning {
        id: key.id(),
        source: Box::new(e),
    })?;
    if &plan.key != key {
        return Err(RenderError::WrongSequence {
            got: plan.key.id(),
            want: key.id(),
        });
    }
    let bad_plan = |reason: &str| RenderError::BadPlan {
        id: key.id(),
        reason: reason.to_string(),
    };
    if plan.appearance.is_none() {
        return Err(bad_plan("the plan has no appearance"));
    }
    if plan.frames.is_empty() {
        return Err(bad_plan("the plan has no frames"));
    }
    let mesh = ctx
        .meshes
        .get(&key.object)
        .cloned()
        .ok_or_else(|| RenderError::NoObjectData {
            what: "mesh",
            object: key.object.clone(),
        })?;
    let out_dir = ctx
        .dataset
        .partial_dir(job.assigned.position, job.attempt)?;
    let head_out_dir = head_partial(&plan, &out_dir)?;
    let parts = if ctx.part_pass {
        let parts = ctx
            .source
            .parts(&key.object)
            .map_err(|e| RenderError::Step {
                what: format!("the part boxes of object '{}'", key.object),
                source: Box::new(e),
            })?;
        if parts.is_empty() {
            return Err(RenderError::NoParts {
                object: key.object.clone(),
            });
        }
        parts
    } else {
        Vec::new()
    };
    let request = RenderRequest {
        id: key.id(),
        object_color: ctx.source.object_color(&key.object),
        object_color_range: ctx.source.object_color_range(&key.object),
        out_dir,
        head_out_dir,
        frame_files: frame_files(plan.frames.len()),
        parts,
        mesh,
        plan: plan.clone(),
    };
    Ok((plan, request))
}

/// The head camera's fresh temporary folder, when the plan has head poses
/// (all frames or none).
fn head_partial(plan: &SequencePlan, out_dir: &Path) -> Result<Option<PathBuf>> {
    let with_head = plan
        .frames
        .iter()
        .filter(|f| f.head_camera.is_some())
        .count();
    if with_head == 0 {
        return Ok(None);
    }
    if with_head != plan.frames.len() {
        return Err(RenderError::BadPlan {
            id: plan.key.id(),
            reason: format!(
                "{with_head} of {} frames have a head camera pose (all or none)",
                plan.frames.len()
            ),
        });
    }
    let dir = DatasetDir::partial_head_dir(out_dir);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| RenderError::io("cannot clear", &dir, e))?;
    }
    std::fs::create_dir_all(&dir).map_err(|e| RenderError::io("cannot create", &dir, e))?;
    Ok(Some(dir))
}
