//! Messages between the parent and a worker: one JSON object per line, the
//! parent writing to the worker's stdin and the worker answering on a
//! private copy of its stdout (Blender's own prints go to stderr).

use super::SceneGeometry;
use grasp_schema::dataset::RenderCost;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Parent to worker.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Request {
    /// First message: build the scene once.
    Init {
        geometry: SceneGeometry,
        settings: serde_json::Value,
    },
    /// Render one sequence into `out_dir`.
    Render(Box<RenderRequest>),
    /// Exit cleanly.
    Quit,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RenderRequest {
    pub id: String,
    pub plan: grasp_schema::SequencePlan,
    pub mesh: MeshFiles,
    /// The object's own colour (linear RGB), used unless the plan randomizes it.
    pub object_color: [f64; 3],
    /// The real object's plausible colours (the catalog's `color`), which
    /// a foreign world draws from; the studio does not read it.
    #[serde(default)]
    pub object_color_range: Option<crate::catalog::ColorRange>,
    pub out_dir: PathBuf,
    /// Where the head camera's frames go, when the plan has head poses.
    #[serde(default)]
    pub head_out_dir: Option<PathBuf>,
    pub frame_files: Vec<String>,
    /// The object's part boxes in catalog order, when the `part` pass is on.
    #[serde(default)]
    pub parts: Vec<super::parts::PartBox>,
}

/// A cached object mesh: little-endian f64 xyz vertices and u32 triangles.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MeshFiles {
    pub object: String,
    pub vertices: PathBuf,
    pub faces: PathBuf,
}

/// Worker to parent.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Response {
    Ready {
        pid: u32,
        /// The device it renders on (`cpu`, `optix`, ...; see
        /// [`super::device`]).
        #[serde(default)]
        device: String,
        /// A line for the log, when `[render] device = "auto"` fell back
        /// to the CPU.
        #[serde(default)]
        note: Option<String>,
    },
    Done {
        id: String,
        seconds: f64,
        /// The worker's peak resident memory so far (Linux VmHWM), KiB.
        #[serde(default)]
        peak_rss_kib: u64,
        /// The worker's resident memory after the sequence (VmRSS), KiB.
        #[serde(default)]
        rss_kib: u64,
        /// Setup and per-camera render seconds.
        #[serde(default)]
        cost: RenderCost,
    },
    Error {
        id: Option<String>,
        message: String,
        /// Retrying cannot help (a configured device Blender lacks): the
        /// parent stops the run.
        #[serde(default)]
        fatal: bool,
    },
}
