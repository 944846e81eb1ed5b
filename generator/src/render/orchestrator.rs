//! The parent side of `grasp-gen render`: plans sequences, hands them to N
//! worker processes, restarts crashed workers and retries their sequences a
//! bounded number of times, recycles workers every `recycle_every`
//! sequences, shows progress, and stops cleanly when `stop` is raised.

use super::protocol::{MeshFiles, RenderRequest, Request, Response};
use super::source::RenderSource;
use super::{RenderConfig, SceneGeometry, Shard};
use crate::dataset::lock::{self, OutputLock};
use crate::dataset::storage;
use crate::dataset::writer::frame_files;
use crate::dataset::{assign_folders, Assigned, DatasetDir};
use anyhow::{anyhow, bail, Context, Result};
use grasp_schema::dataset::{RenderCost, SequenceRecord, PART_LABELS_KEY, RENDER_COST_KEY};
use grasp_schema::SequencePlan;
use grasp_support::atomic::write_atomic;
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

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

#[derive(Debug, Clone, Default)]
pub struct RenderSummary {
    /// Sequences in this shard.
    pub in_shard: usize,
    /// Already finished before this run (`--resume`).
    pub skipped: usize,
    /// Looked finished but had missing or damaged files: rendered again.
    pub redone: usize,
    pub rendered: usize,
    pub frames: usize,
    pub retries: usize,
    /// (sequence id, last error) of sequences that failed every attempt.
    pub failed: Vec<(String, String)>,
    pub seconds: f64,
    pub interrupted: bool,
    /// Why the run stopped early on its own (a full disk, a lost lock).
    pub fatal: Option<String>,
    /// Largest peak resident memory reported by any worker, KiB.
    pub peak_worker_rss_kib: u64,
    /// The devices this run's sequences were rendered on (`render.cost.device`).
    pub devices: BTreeSet<String>,
    /// Why `[render] device = "auto"` rendered on the CPU, logged once.
    pub device_note: Option<String>,
}

impl RenderSummary {
    pub fn frames_per_second(&self) -> f64 {
        self.frames as f64 / self.seconds.max(1e-9)
    }
}

struct Job {
    assigned: Assigned,
    attempt: u32,
}

enum Event {
    Rendered {
        peak_rss_kib: u64,
        cost: Box<RenderCost>,
        /// Part names in label order (the `part` pass), else empty.
        part_labels: Vec<String>,
        job: Job,
        plan: Box<SequencePlan>,
        partial: PathBuf,
        files: Vec<String>,
    },
    Retry {
        id: String,
        error: String,
    },
    Failed {
        id: String,
        error: String,
    },
    /// A worker's note for the log (the device fallback), once per start.
    Note(String),
    /// Nothing more can be written (a full disk), or no worker can start
    /// as configured: stop the whole run.
    Fatal {
        id: String,
        error: String,
    },
}

/// What every worker thread shares.
struct Shared {
    source: Arc<dyn RenderSource>,
    dataset: DatasetDir,
    geometry: SceneGeometry,
    settings: serde_json::Value,
    meshes: BTreeMap<String, MeshFiles>,
    exe: PathBuf,
    worker_env: Vec<(String, String)>,
    recycle_every: usize,
    max_retries: u32,
    /// Whether the `part` pass is on (requests then carry the part boxes).
    part_pass: bool,
    queue: Mutex<VecDeque<Job>>,
    stop: Arc<AtomicBool>,
    /// The live worker process of each slot, so the main thread can kill it.
    children: Mutex<Vec<Option<Arc<Mutex<Child>>>>>,
    /// Prefix of the worker log names: shards sharing a folder keep apart.
    log_prefix: String,
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
        bail!(
            "{} already holds {finished_count} finished sequences of this dataset; pass \
             --resume to keep them and render the rest, or choose an empty folder",
            opts.out.display()
        );
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
        let scene_json = serde_json::to_vec_pretty(&source.scene())?;
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

/// Fails when a finished folder holds another sequence than the one this
/// config plans there: the folder was rendered with other settings (more or
/// fewer sequences per pair, other objects, parts or conditions), which
/// number the folders differently. Keeping it would leave one sequence
/// twice and another missing; rendering over it would destroy it.
/// Fails too when a finished sequence was rendered with other `[render]`
/// settings that change pixels ([`super::consistency`]), or when the first
/// finished sequence differs from a fresh plan (another resolution, seed or
/// planning setting; one plan, not all: planning every finished sequence
/// would slow each resume): resuming would mix two renders in one dataset.
fn refuse_other_sequences(
    source: &dyn RenderSource,
    dataset: &DatasetDir,
    in_shard: &[Assigned],
    finished: &[bool],
    config: &RenderConfig,
) -> Result<()> {
    // One record at a time: a large dataset's records do not fit in memory.
    let mut other_key = Mismatches::default();
    let mut other_render = Mismatches::default();
    let mut sample: Option<(PathBuf, SequencePlan)> = None;
    for (a, _) in in_shard.iter().zip(finished).filter(|(_, done)| **done) {
        let path = dataset
            .root
            .join(&a.rel_dir)
            .join(grasp_schema::dataset::SEQUENCE_FILE);
        let Ok(record) = crate::dataset::writer::read_record(&path) else {
            continue;
        };
        if record.plan.key == a.planned.key && sample.is_none() {
            sample = Some((dataset.root.join(&a.rel_dir), record.plan.clone()));
        }
        if record.plan.key != a.planned.key {
            other_key.add(|| {
                format!(
                    "{} holds sequence {}, but this config plans {} there",
                    dataset.root.join(&a.rel_dir).display(),
                    record.plan.key.id(),
                    a.planned.key.id()
                )
            });
        }
        let changes = super::consistency::changed_settings(config, &record.render);
        if !changes.is_empty() {
            other_render.add(|| {
                format!(
                    "{}: {}",
                    dataset.root.join(&a.rel_dir).display(),
                    super::consistency::describe(&changes)
                )
            });
        }
    }
    if let Some(first) = other_key.first {
        bail!(
            "{first} ({} more such folder(s)): the dataset was rendered with other settings \
             (sequences per pair, objects, parts or conditions number the folders); render into \
             a new folder, or back to the old settings",
            other_key.count - 1
        );
    }
    if let Some(first) = other_render.first {
        bail!(
            "{first} ({} more finished sequence(s) differ); resuming would mix two renders in \
             one dataset: set the render settings back, or render into a new folder",
            other_render.count - 1
        );
    }
    match sample {
        Some((dir, recorded)) => refuse_other_plan(source, &dir, &recorded),
        None => Ok(()),
    }
}

/// Fails when a finished sequence's plan is not what the config plans for
/// it now, naming `[plan.camera] resolution` when that is what changed.
fn refuse_other_plan(source: &dyn RenderSource, dir: &Path, recorded: &SequencePlan) -> Result<()> {
    let id = recorded.key.id();
    // The same JSON round trip as the record, so floats compare exactly.
    let fresh = source.plan(&recorded.key).and_then(|p| {
        let text = serde_json::to_string(&p)?;
        Ok(serde_json::from_str::<SequencePlan>(&text)?)
    });
    let fresh = fresh.with_context(|| format!("re-planning finished sequence {id}"))?;
    if &fresh == recorded {
        return Ok(());
    }
    let size = |p: &SequencePlan| format!("{}x{}", p.intrinsics.width, p.intrinsics.height);
    let what = match size(&fresh) == size(recorded) {
        true => format!(
            "its sequence.json differs from a fresh plan of {id} (another seed, code, or \
             [dataset], [plan], [appearance] or [randomize] setting)"
        ),
        false => format!(
            "[plan.camera] resolution: rendered at {}, the config plans {}",
            size(recorded),
            size(&fresh)
        ),
    };
    bail!(
        "{}: {what}; resuming would mix two datasets in one folder: set the settings back, or \
         render into a new folder",
        dir.display()
    )
}

/// The first of a kind of mismatch, described, and how many there are.
#[derive(Default)]
struct Mismatches {
    first: Option<String>,
    count: usize,
}

impl Mismatches {
    fn add(&mut self, describe: impl FnOnce() -> String) {
        if self.first.is_none() {
            self.first = Some(describe());
        }
        self.count += 1;
    }
}

/// The jobs of this run: the unfinished sequences of the shard, and the
/// finished-looking ones whose files are missing or damaged (re-rendered,
/// with a message).
fn unfinished_jobs(
    dataset: &DatasetDir,
    in_shard: &[Assigned],
    finished: &[bool],
    summary: &mut RenderSummary,
) -> VecDeque<Job> {
    let mut todo = VecDeque::new();
    for (a, done) in in_shard.iter().zip(finished) {
        if *done {
            match dataset.check_finished(&a.rel_dir) {
                Ok(()) => {
                    summary.skipped += 1;
                    continue;
                }
                Err(reason) => {
                    tracing::warn!("re-rendering {}: {reason}", a.rel_dir);
                    summary.redone += 1;
                }
            }
        }
        todo.push_back(Job {
            assigned: a.clone(),
            attempt: 0,
        });
    }
    todo
}

/// Rewrites the manifest from the folders. A shard sharing its folder with
/// other running shards leaves it to the last one to finish (each appended
/// its lines as it went): the lock is released first, then the manifest is
/// rebuilt if no other run holds a lock.
fn finish_manifest(dataset: &DatasetDir, shard: Shard, lock: OutputLock) -> Result<()> {
    if shard == Shard::ALL {
        dataset.rebuild_manifest()?;
        return Ok(());
    }
    drop(lock);
    let others = lock::holders(&dataset.work_dir());
    if others.is_empty() {
        dataset.rebuild_manifest()?;
    } else {
        tracing::info!(
            "{} other run(s) still write into {}: the last one rewrites the manifest",
            others.len(),
            dataset.root.display()
        );
    }
    Ok(())
}

/// Writes each needed object's mesh once, as raw little-endian arrays the
/// workers pass to Blender without parsing.
fn write_meshes(
    source: &dyn RenderSource,
    dataset: &DatasetDir,
    todo: &VecDeque<Job>,
) -> Result<BTreeMap<String, MeshFiles>> {
    let dir = dataset.work_dir().join("meshes");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut out = BTreeMap::new();
    for job in todo {
        let object = &job.assigned.planned.key.object;
        if out.contains_key(object) {
            continue;
        }
        let mesh = source
            .mesh(object)
            .with_context(|| format!("loading the mesh of object '{object}'"))?;
        let vertices: Vec<u8> = mesh
            .vertices
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let faces: Vec<u8> = mesh
            .faces
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let files = MeshFiles {
            object: object.clone(),
            vertices: dir.join(format!("{object}.vertices.f64")),
            faces: dir.join(format!("{object}.faces.u32")),
        };
        write_atomic(&files.vertices, &vertices)?;
        write_atomic(&files.faces, &faces)?;
        out.insert(object.clone(), files);
    }
    Ok(out)
}

/// How often a render without a progress bar logs its progress.
const PROGRESS_LOG_INTERVAL: Duration = Duration::from_secs(30);

fn progress_bar(total: usize, show: bool) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(total as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30.cyan/blue} {pos}/{len} sequences  {msg}  ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.enable_steady_tick(Duration::from_millis(250));
    pb
}

fn run_pool(
    ctx: &Arc<Shared>,
    workers: usize,
    total: usize,
    show_progress: bool,
    lock: &OutputLock,
    summary: &mut RenderSummary,
) -> Result<bool> {
    let (tx, rx) = channel();
    let threads: Vec<_> = (0..workers)
        .map(|slot| {
            let (ctx, tx) = (ctx.clone(), tx.clone());
            std::thread::spawn(move || worker_slot(slot, &ctx, &tx))
        })
        .collect();
    drop(tx);
    let pb = progress_bar(total, show_progress);
    let start = Instant::now();
    // Without a terminal (a log file, a cluster's output) the bar draws
    // nothing: a line every 30 s instead.
    let log_lines = !std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut last_line = start;
    // Messages go through the log (stderr) in every mode; the bar steps
    // aside while they print.
    let log = |f: &dyn Fn()| pb.suspend(f);
    while summary.rendered + summary.failed.len() < total {
        if ctx.stop.load(Ordering::SeqCst) {
            log(&|| {
                tracing::warn!(
                    "interrupted: stopping workers; finished sequences are kept (use --resume)"
                )
            });
            break;
        }
        if lock.lost() {
            summary.fatal = Some(format!(
                "the output lock {} was taken over by another run",
                lock.path().display()
            ));
            break;
        }
        match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(Event::Rendered {
                peak_rss_kib,
                cost,
                part_labels,
                job,
                plan,
                partial,
                files,
            }) => {
                let frames = plan.frames.len();
                summary.devices.insert(cost.device.clone());
                summary.peak_worker_rss_kib = summary.peak_worker_rss_kib.max(peak_rss_kib);
                let record = SequenceRecord {
                    plan: *plan,
                    frame_files: files,
                    render: record_settings(&ctx.settings, &cost, &part_labels),
                    generator_version: env!("CARGO_PKG_VERSION").to_string(),
                };
                let id = job.assigned.planned.key.id();
                match ctx.dataset.finish(&partial, &job.assigned.rel_dir, &record) {
                    Ok(()) => {
                        summary.rendered += 1;
                        summary.frames += frames;
                    }
                    Err(e) if storage::is_storage_full(&e) => {
                        let _ = std::fs::remove_dir_all(&partial);
                        summary.fatal = Some(format!("{id}: {e:#}"));
                        break;
                    }
                    Err(e) => {
                        let error = format!("{e:#}");
                        log(&|| tracing::error!("FAILED {id}: {error}"));
                        summary.failed.push((id, error));
                    }
                }
                pb.inc(1);
                let fps = summary.frames as f64 / start.elapsed().as_secs_f64().max(1e-9);
                pb.set_message(format!("{fps:.2} frames/s"));
                if log_lines && last_line.elapsed() >= PROGRESS_LOG_INTERVAL {
                    last_line = Instant::now();
                    let done = summary.rendered + summary.failed.len();
                    tracing::info!(
                        "{}",
                        grasp_support::cli::progress_line(
                            "render",
                            done as u64,
                            total as u64,
                            start.elapsed(),
                            &format!("{fps:.2} frames/s, {} failed", summary.failed.len()),
                        )
                    );
                }
            }
            Ok(Event::Note(note)) => {
                // Every worker start says it again; once is enough.
                if summary.device_note.is_none() {
                    log(&|| tracing::warn!("{note}"));
                    summary.device_note = Some(note);
                }
            }
            Ok(Event::Retry { id, error }) => {
                summary.retries += 1;
                log(&|| tracing::warn!("retrying {id}: {}", first_line(&error)));
            }
            Ok(Event::Failed { id, error }) => {
                log(&|| tracing::error!("FAILED {id}: {error}"));
                summary.failed.push((id, error));
                pb.inc(1);
            }
            Ok(Event::Fatal { id, error }) => {
                summary.fatal = Some(format!("{id}: {error}"));
                break;
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
    pb.finish_and_clear();
    // Whether the user stopped us, before stopping the workers ourselves.
    let interrupted = ctx.stopped();
    ctx.stop_and_kill();
    for t in threads {
        if t.join().is_err() {
            return Err(anyhow!("a worker thread panicked"));
        }
    }
    Ok(interrupted)
}

/// The render settings plus this sequence's cost and part names, as stored
/// in its record.
fn record_settings(
    settings: &serde_json::Value,
    cost: &RenderCost,
    part_labels: &[String],
) -> serde_json::Value {
    let mut v = settings.clone();
    if let (Some(map), Ok(c)) = (v.as_object_mut(), serde_json::to_value(cost)) {
        map.insert(RENDER_COST_KEY.to_string(), c);
        if !part_labels.is_empty() {
            map.insert(PART_LABELS_KEY.to_string(), serde_json::json!(part_labels));
        }
    }
    v
}

fn first_line(s: &str) -> &str {
    s.lines().last().unwrap_or(s)
}

impl Shared {
    fn stop_and_kill(&self) {
        self.stop.store(true, Ordering::SeqCst);
        let children = self.children.lock().unwrap_or_else(|e| e.into_inner());
        for child in children.iter().flatten() {
            let mut c = child.lock().unwrap_or_else(|e| e.into_inner());
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    fn worker_log(&self, slot: usize) -> PathBuf {
        self.dataset
            .work_dir()
            .join("logs")
            .join(format!("{}worker-{slot}.log", self.log_prefix))
    }
}

/// A live worker process.
struct WorkerProc {
    child: Arc<Mutex<Child>>,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    /// What the worker asked to be logged when it started.
    note: Option<String>,
}

/// A worker that cannot start as configured (a `[render] device` Blender
/// does not offer): every retry would fail the same way.
#[derive(Debug, thiserror::Error)]
#[error("worker failed to start: {0}")]
struct CannotStart(String);

impl WorkerProc {
    fn spawn(slot: usize, ctx: &Shared) -> Result<Self> {
        let log_path = ctx.worker_log(slot);
        if let Some(logs) = log_path.parent() {
            std::fs::create_dir_all(logs)?;
        }
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log_path)
            .with_context(|| format!("cannot open {}", log_path.display()))?;
        let mut child = Command::new(&ctx.exe)
            .arg("worker")
            .envs(ctx.worker_env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(log)
            // Own process group: a terminal Ctrl-C reaches only the parent,
            // which then stops the workers itself.
            .process_group(0)
            .spawn()
            .with_context(|| format!("cannot start worker {}", ctx.exe.display()))?;
        let stdin = child.stdin.take().context("worker stdin")?;
        let stdout = BufReader::new(child.stdout.take().context("worker stdout")?);
        let mut proc = WorkerProc {
            child: Arc::new(Mutex::new(child)),
            stdin,
            stdout,
            note: None,
        };
        ctx.children.lock().unwrap_or_else(|e| e.into_inner())[slot] = Some(proc.child.clone());
        let init = Request::Init {
            geometry: ctx.geometry.clone(),
            settings: ctx.settings.clone(),
        };
        match proc.call(&init, &log_path)? {
            Response::Ready { note, .. } => Ok(WorkerProc { note, ..proc }),
            Response::Error {
                message,
                fatal: true,
                ..
            } => Err(CannotStart(message).into()),
            Response::Error { message, .. } => bail!("worker failed to start: {message}"),
            other => bail!("unexpected worker answer {other:?}"),
        }
    }

    fn call(&mut self, request: &Request, log: &Path) -> Result<Response> {
        let mut line = serde_json::to_string(request)?;
        line.push('\n');
        let sent = self
            .stdin
            .write_all(line.as_bytes())
            .and_then(|_| self.stdin.flush());
        let mut answer = String::new();
        let read = sent.and_then(|_| self.stdout.read_line(&mut answer));
        match read {
            Ok(n) if n > 0 => serde_json::from_str(&answer)
                .with_context(|| format!("invalid worker answer '{}'", answer.trim())),
            _ => {
                let status = self.kill();
                bail!("worker process died ({status}); see {}", log.display())
            }
        }
    }

    fn kill(&mut self) -> String {
        let mut c = self.child.lock().unwrap_or_else(|e| e.into_inner());
        let _ = c.kill();
        c.wait()
            .map(|s| s.to_string())
            .unwrap_or_else(|e| e.to_string())
    }

    fn quit(mut self) {
        let _ = self
            .stdin
            .write_all(b"{\"type\":\"quit\"}\n")
            .and_then(|_| self.stdin.flush());
        drop(self.stdin);
        let mut c = self.child.lock().unwrap_or_else(|e| e.into_inner());
        let _ = c.wait();
    }
}

/// One worker slot: takes jobs until the queue is empty or stop is raised.
fn worker_slot(slot: usize, ctx: &Shared, tx: &Sender<Event>) {
    let mut proc: Option<WorkerProc> = None;
    let mut served = 0;
    let log = ctx.worker_log(slot);
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
        let prepared = prepare(ctx, &job);
        let (plan, request) = match prepared {
            Ok(p) => p,
            Err(e) => {
                let _ = tx.send(Event::Failed {
                    id,
                    error: format!("{e:#}"),
                });
                continue;
            }
        };
        let partial = request.out_dir.clone();
        let files = request.frame_files.clone();
        let head_partial = request.head_out_dir.clone();
        let part_labels: Vec<String> = request.parts.iter().map(|p| p.name.clone()).collect();
        let outcome = (|| -> Result<(u64, RenderCost)> {
            if proc.is_none() {
                let mut started = WorkerProc::spawn(slot, ctx)?;
                if let Some(note) = started.note.take() {
                    let _ = tx.send(Event::Note(note));
                }
                proc = Some(started);
            }
            let p = proc.as_mut().expect("worker started above");
            match p.call(&Request::Render(Box::new(request)), &log) {
                Ok(Response::Done {
                    peak_rss_kib,
                    rss_kib,
                    cost,
                    ..
                }) => {
                    // RUST_LOG=generator::render=debug traces worker memory.
                    tracing::debug!(slot, served, rss_kib, peak_rss_kib, "worker memory");
                    Ok((peak_rss_kib, cost))
                }
                Ok(Response::Error { message, .. }) => Err(anyhow!(message)),
                Ok(other) => Err(anyhow!("unexpected worker answer {other:?}")),
                Err(e) => {
                    proc = None;
                    Err(e)
                }
            }
        })();
        match outcome {
            Ok((peak_rss_kib, cost)) => {
                served += 1;
                let _ = tx.send(Event::Rendered {
                    peak_rss_kib,
                    cost: Box::new(cost),
                    part_labels,
                    job,
                    plan: Box::new(plan),
                    partial,
                    files,
                });
                if served >= ctx.recycle_every {
                    if let Some(p) = proc.take() {
                        p.quit();
                    }
                    served = 0;
                }
            }
            Err(e) => {
                let _ = std::fs::remove_dir_all(&partial);
                if let Some(h) = &head_partial {
                    let _ = std::fs::remove_dir_all(h);
                }
                if ctx.stopped() {
                    break;
                }
                if e.downcast_ref::<CannotStart>().is_some() {
                    let error = format!("{e:#}");
                    let _ = tx.send(Event::Fatal { id, error });
                    break;
                }
                // A full disk fails every sequence alike: stop, do not retry.
                let full = match storage::is_storage_full(&e) {
                    true => None,
                    false => storage::probe(&ctx.dataset.work_dir().join("partial")),
                };
                if storage::is_storage_full(&e) || full.is_some() {
                    let error = match full {
                        Some(f) => format!("{e:#}; {:#}", anyhow::Error::new(f)),
                        None => format!("{e:#}"),
                    };
                    let _ = tx.send(Event::Fatal { id, error });
                    break;
                }
                let error = format!("{e:#}");
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
            }
        }
    }
    if let Some(p) = proc.take() {
        p.quit();
    }
}

/// Plans a job and builds its render request.
fn prepare(ctx: &Shared, job: &Job) -> Result<(SequencePlan, RenderRequest)> {
    let key = &job.assigned.planned.key;
    let plan = ctx
        .source
        .plan(key)
        .with_context(|| format!("planning sequence {}", key.id()))?;
    if &plan.key != key {
        bail!(
            "the planner returned sequence {} for {}",
            plan.key.id(),
            key.id()
        );
    }
    if plan.appearance.is_none() {
        bail!("sequence {}: the plan has no appearance", key.id());
    }
    if plan.frames.is_empty() {
        bail!("sequence {}: the plan has no frames", key.id());
    }
    let mesh = ctx
        .meshes
        .get(&key.object)
        .cloned()
        .with_context(|| format!("no mesh for object '{}'", key.object))?;
    let out_dir = ctx
        .dataset
        .partial_dir(job.assigned.position, job.attempt)?;
    let head_out_dir = head_partial(&plan, &out_dir)?;
    let parts = if ctx.part_pass {
        let parts = ctx
            .source
            .parts(&key.object)
            .with_context(|| format!("the part boxes of object '{}'", key.object))?;
        if parts.is_empty() {
            bail!("object '{}' has no parts to label", key.object);
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
        bail!(
            "sequence {}: {with_head} of {} frames have a head camera pose (all or none)",
            plan.key.id(),
            plan.frames.len()
        );
    }
    let dir = DatasetDir::partial_head_dir(out_dir);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).with_context(|| format!("cannot clear {}", dir.display()))?;
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(Some(dir))
}
