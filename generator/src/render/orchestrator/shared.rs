//! What the orchestrator's files share: a job, what a worker slot tells
//! the parent ([`Event`]), a rendered sequence, the state every worker
//! thread reads ([`Shared`]) and the run's [`RenderSummary`]. It imports
//! nothing of the orchestrator's own, so each of its files can.

use crate::dataset::{Assigned, DatasetDir};
use crate::render::protocol::MeshFiles;
use crate::render::scene::SceneGeometry;
use crate::render::source::RenderSource;
use grasp_schema::dataset::RenderCost;
use grasp_schema::SequencePlan;
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::PathBuf;
use std::process::Child;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

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

pub(super) struct Job {
    pub(super) assigned: Assigned,
    pub(super) attempt: u32,
}

/// What a worker slot tells the parent.
pub(super) enum Event {
    Rendered(Box<Rendered>),
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

/// A sequence rendered into its partial folder, to be moved into place.
pub(super) struct Rendered {
    pub(super) peak_rss_kib: u64,
    pub(super) cost: RenderCost,
    /// Part names in label order (the `part` pass), else empty.
    pub(super) part_labels: Vec<String>,
    pub(super) job: Job,
    pub(super) plan: SequencePlan,
    pub(super) partial: PathBuf,
    pub(super) files: Vec<String>,
}

/// What every worker thread shares.
pub(super) struct Shared {
    pub(super) source: Arc<dyn RenderSource>,
    pub(super) dataset: DatasetDir,
    pub(super) geometry: SceneGeometry,
    pub(super) settings: serde_json::Value,
    pub(super) meshes: BTreeMap<String, MeshFiles>,
    pub(super) exe: PathBuf,
    pub(super) worker_env: Vec<(String, String)>,
    pub(super) recycle_every: usize,
    pub(super) max_retries: u32,
    /// Whether the `part` pass is on (requests then carry the part boxes).
    pub(super) part_pass: bool,
    pub(super) queue: Mutex<VecDeque<Job>>,
    pub(super) stop: Arc<AtomicBool>,
    /// The live worker process of each slot, so the main thread can kill it.
    pub(super) children: Mutex<Vec<Option<Arc<Mutex<Child>>>>>,
    /// Prefix of the worker log names: shards sharing a folder keep apart.
    pub(super) log_prefix: String,
}

impl Shared {
    pub(super) fn stop_and_kill(&self) {
        self.stop.store(true, Ordering::SeqCst);
        let children = self.children.lock().unwrap_or_else(|e| e.into_inner());
        for child in children.iter().flatten() {
            let mut c = child.lock().unwrap_or_else(|e| e.into_inner());
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    pub(super) fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    pub(super) fn worker_log(&self, slot: usize) -> PathBuf {
        self.dataset
            .work_dir()
            .join("logs")
            .join(format!("{}worker-{slot}.log", self.log_prefix))
    }
}
