//! The parent's loop over a running pool: one thread per worker slot, the
//! events they send (rendered, retried, failed, fatal) turned into finished
//! folders and the run's summary, and the progress shown meanwhile.

use super::outputs::record_settings;
use super::shared::{Event, RenderSummary, Rendered, Shared};
use super::slot::worker_slot;
use crate::dataset::error::chain;
use crate::dataset::lock::OutputLock;
use crate::dataset::storage;
use crate::render::error::{RenderError, Result};
use grasp_schema::dataset::SequenceRecord;
use indicatif::{ProgressBar, ProgressStyle};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How often a render without a progress bar logs its progress.
const PROGRESS_LOG_INTERVAL: Duration = Duration::from_secs(30);

/// Runs `workers` slots over the queue until every sequence is done or the
/// run stops; true when the user interrupted it.
pub(super) fn run_pool(
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
    let mut progress = Progress::new(total, show_progress);
    while summary.rendered + summary.failed.len() < total {
        if ctx.stop.load(Ordering::SeqCst) {
            progress.log(&|| {
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
            Ok(event) => {
                if !on_event(ctx, event, summary, &mut progress) {
                    break;
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
    progress.pb.finish_and_clear();
    // Whether the user stopped us, before stopping the workers ourselves.
    let interrupted = ctx.stopped();
    ctx.stop_and_kill();
    for t in threads {
        if t.join().is_err() {
            return Err(RenderError::WorkerPanicked);
        }
    }
    Ok(interrupted)
}

/// Takes one worker event into the summary; false when the run must stop.
fn on_event(
    ctx: &Shared,
    event: Event,
    summary: &mut RenderSummary,
    progress: &mut Progress,
) -> bool {
    match event {
        Event::Rendered(rendered) => return on_rendered(ctx, *rendered, summary, progress),
        Event::Note(note) => {
            // Every worker start says it again; once is enough.
            if summary.device_note.is_none() {
                progress.log(&|| tracing::warn!("{note}"));
                summary.device_note = Some(note);
            }
        }
        Event::Retry { id, error } => {
            summary.retries += 1;
            progress.log(&|| tracing::warn!("retrying {id}: {}", first_line(&error)));
        }
        Event::Failed { id, error } => {
            progress.log(&|| tracing::error!("FAILED {id}: {error}"));
            summary.failed.push((id, error));
            progress.pb.inc(1);
        }
        Event::Fatal { id, error } => {
            summary.fatal = Some(format!("{id}: {error}"));
            return false;
        }
    }
    true
}

/// Moves a rendered sequence into its folder with its record; false when
/// nothing more can be written (a full disk).
fn on_rendered(
    ctx: &Shared,
    rendered: Rendered,
    summary: &mut RenderSummary,
    progress: &mut Progress,
) -> bool {
    let Rendered {
        peak_rss_kib,
        cost,
        part_labels,
        job,
        plan,
        partial,
        files,
    } = rendered;
    let frames = plan.frames.len();
    summary.devices.insert(cost.device.clone());
    summary.peak_worker_rss_kib = summary.peak_worker_rss_kib.max(peak_rss_kib);
    let record = SequenceRecord {
        plan,
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
            summary.fatal = Some(format!("{id}: {}", chain(&e)));
            return false;
        }
        Err(e) => {
            let error = chain(&e);
            progress.log(&|| tracing::error!("FAILED {id}: {error}"));
            summary.failed.push((id, error));
        }
    }
    progress.advance(summary);
    true
}

/// The bar on a terminal; without one (a log file, a cluster's output) the
/// bar draws nothing, so a line every [`PROGRESS_LOG_INTERVAL`] instead.
struct Progress {
    pb: ProgressBar,
    total: usize,
    start: Instant,
    log_lines: bool,
    last_line: Instant,
}

impl Progress {
    fn new(total: usize, show: bool) -> Self {
        let start = Instant::now();
        Progress {
            pb: progress_bar(total, show),
            total,
            start,
            log_lines: !std::io::IsTerminal::is_terminal(&std::io::stderr()),
            last_line: start,
        }
    }

    /// Messages go through the log (stderr) in every mode; the bar steps
    /// aside while they print.
    fn log(&self, f: &dyn Fn()) {
        self.pb.suspend(f)
    }

    /// One more sequence rendered: the bar, and the log line when due.
    fn advance(&mut self, summary: &RenderSummary) {
        self.pb.inc(1);
        let fps = summary.frames as f64 / self.start.elapsed().as_secs_f64().max(1e-9);
        self.pb.set_message(format!("{fps:.2} frames/s"));
        if self.log_lines && self.last_line.elapsed() >= PROGRESS_LOG_INTERVAL {
            self.last_line = Instant::now();
            let done = summary.rendered + summary.failed.len();
            tracing::info!(
                "{}",
                grasp_support::progress::progress_line(
                    "render",
                    done as u64,
                    self.total as u64,
                    self.start.elapsed(),
                    &format!("{fps:.2} frames/s, {} failed", summary.failed.len()),
                )
            );
        }
    }
}

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

fn first_line(s: &str) -> &str {
    s.lines().last().unwrap_or(s)
}
