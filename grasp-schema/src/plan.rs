//! A sequence plan: everything the renderer needs to draw one reach, frame by
//! frame. Plans are produced by the generator's planner (pure Rust, seeded) and
//! consumed by the Blender workers; they are also embedded in each sequence's
//! `sequence.json`, so a dataset records every value that made it.
//!
//! World frame: right-handed, metres, Z up, the floor at z = 0.
//! Camera frame (Blender convention): the camera looks along its local -Z, with
//! +Y up in the image and +X to the right.

use crate::appearance::Appearance;
use crate::taxonomy::{Class, GraspType, Preshape};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

/// Version of the plan / sequence.json format. Bump on incompatible change.
pub const PLAN_SCHEMA_VERSION: u32 = 1;

/// The condition a sequence is generated for, mirroring the paper's test sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Condition {
    /// Training and "same person"-like sequences.
    Default,
    /// The same start distance, completed in half the time.
    Fast,
    /// The arm starts hanging along the body, rises, then approaches.
    FromGround,
    /// Lower and closer start, curved approach.
    Seated,
    /// Default trajectories rendered with the held-out texture family.
    Background,
    /// Default trajectories rendered with an appearance training never
    /// draws: texture families, lights, lens, tone mapping and sensor
    /// effects of its own.
    UnseenLook,
}

impl Condition {
    pub const ALL: [Condition; 6] = [
        Condition::Default,
        Condition::Fast,
        Condition::FromGround,
        Condition::Seated,
        Condition::Background,
        Condition::UnseenLook,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Condition::Default => "default",
            Condition::Fast => "fast",
            Condition::FromGround => "from_ground",
            Condition::Seated => "seated",
            Condition::Background => "background",
            Condition::UnseenLook => "unseen_look",
        }
    }
}

impl fmt::Display for Condition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Condition {
    type Err = crate::taxonomy::UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Condition::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| crate::taxonomy::UnknownName {
                kind: "condition",
                name: s.to_string(),
                expected: Condition::ALL.map(|c| c.name()).join(", "),
            })
    }
}

/// Identifies one sequence. Together with the dataset seed and the generator
/// config it determines the plan completely.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct SequenceKey {
    pub object: String,
    /// Name of the grasp part (unique within the object).
    pub part: String,
    pub index: u32,
    pub condition: Condition,
}

impl SequenceKey {
    /// The seed of this sequence's own random stream: a stable hash of the
    /// dataset seed and the key, identical on every machine and every run.
    pub fn stream_seed(&self, dataset_seed: u64) -> u64 {
        let mut h = Fnv1a::new();
        h.write(&dataset_seed.to_le_bytes());
        h.write(self.object.as_bytes());
        h.write(&[0xff]);
        h.write(self.part.as_bytes());
        h.write(&[0xff]);
        h.write(&self.index.to_le_bytes());
        h.write(self.condition.name().as_bytes());
        splitmix64(h.finish())
    }

    /// A readable unique id, e.g. `025_mug/handle/default/00012`.
    pub fn id(&self) -> String {
        format!(
            "{}/{}/{}/{:05}",
            self.object, self.part, self.condition, self.index
        )
    }
}

/// Seed of a named sub-stream of a sequence stream (e.g. "trajectory",
/// "appearance"), so adding draws to one never shifts the others.
pub fn substream_seed(stream_seed: u64, name: &str) -> u64 {
    let mut h = Fnv1a::new();
    h.write(&stream_seed.to_le_bytes());
    h.write(name.as_bytes());
    splitmix64(h.finish())
}

struct Fnv1a(u64);
impl Fnv1a {
    fn new() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }
    fn finish(&self) -> u64 {
        self.0
    }
}

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A rigid pose: position (metres) and unit quaternion, scalar first.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: [f64; 3],
    pub rotation_wxyz: [f64; 4],
}

/// Pinhole intrinsics of the rendered camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    pub width: u32,
    pub height: u32,
    /// Focal lengths and principal point in pixels.
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub fov_x_deg: f64,
    pub fov_y_deg: f64,
    pub clip_near: f64,
    pub clip_far: f64,
}

/// One planned frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FramePlan {
    pub index: u32,
    /// Seconds since movement onset.
    pub time_s: f64,
    /// Pose of the wrist camera in the world frame.
    pub camera: Pose,
    /// Ground-truth class of the frame (the part's pre-shape, or `no_grasp`).
    pub class: Class,
    /// Optional second (egocentric, head-mounted) camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub head_camera: Option<Pose>,
}

/// The placed object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectPlacement {
    /// Pose of the object frame (catalog frame) in the world.
    pub pose: Pose,
    pub yaw_deg: f64,
    pub upside_down: bool,
    pub on_table_border: bool,
}

/// An object on the table that is not the target: it never holds the
/// target part, never overlaps the target object or blocks the planned
/// reach, and never carries a label.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Distractor {
    /// `box`, `cylinder` (axis along its local Z) or `sphere`.
    pub shape: String,
    /// Full extents along the local X, Y, Z axes, metres (a sphere's are
    /// equal; a cylinder's X and Y are its diameter).
    pub size: [f64; 3],
    /// Centre and orientation in the world; it rests on the table top.
    pub pose: Pose,
    /// Linear RGB.
    pub color: [f64; 3],
    pub roughness: f64,
}

/// Everything needed to render one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequencePlan {
    pub schema_version: u32,
    pub dataset_seed: u64,
    pub key: SequenceKey,
    pub stream_seed: u64,
    pub category: String,
    pub grasp_type: GraspType,
    pub preshape: Preshape,
    /// Index of the part in the catalog's object file.
    pub part_index: usize,
    pub fps: f64,
    pub duration_s: f64,
    pub intrinsics: CameraIntrinsics,
    pub object: ObjectPlacement,
    /// Target point (world) the approach ends at, and the box's other end.
    pub target: [f64; 3],
    pub other_end: [f64; 3],
    pub frames: Vec<FramePlan>,
    /// Every value drawn from the sequence's random stream for the trajectory
    /// (start point, wrist timings, resampling attempts...), by name.
    pub sampled: BTreeMap<String, serde_json::Value>,
    /// Domain randomization (materials, lights, exposure, hand visibility).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<Appearance>,
    /// Distractor objects on the table (none unless the lever is on).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub distractors: Vec<Distractor>,
}

impl SequencePlan {
    /// Frame classes in order.
    pub fn labels(&self) -> Vec<Class> {
        self.frames.iter().map(|f| f.class).collect()
    }
}
