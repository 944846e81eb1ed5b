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

impl Pose {
    /// A world point in this pose's frame (the inverse rotation of the
    /// offset, quaternion form: v + 2u x (u x v + w v) with u = -q.xyz).
    pub fn to_local(&self, world: [f64; 3]) -> [f64; 3] {
        let [w, x, y, z] = self.rotation_wxyz;
        let norm = (w * w + x * x + y * y + z * z).sqrt();
        let (w, u) = (w / norm, [-x / norm, -y / norm, -z / norm]);
        let v = [
            world[0] - self.position[0],
            world[1] - self.position[1],
            world[2] - self.position[2],
        ];
        let uv = cross(u, v);
        let inner = [uv[0] + w * v[0], uv[1] + w * v[1], uv[2] + w * v[2]];
        let t = cross(u, inner);
        [v[0] + 2.0 * t[0], v[1] + 2.0 * t[1], v[2] + 2.0 * t[2]]
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
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

impl CameraIntrinsics {
    /// The focal length in pixels along the image's shorter side (`fy` for
    /// a landscape image, `fx` for a portrait one): the one a centred
    /// square crop's angle follows.
    pub fn shorter_side_focal(&self) -> f64 {
        if self.height <= self.width {
            self.fy
        } else {
            self.fx
        }
    }

    /// Whether a point in the camera's frame (Blender's: looking along -Z,
    /// +Y up in the image) projects inside the image, in front of the lens.
    pub fn sees(&self, p: [f64; 3]) -> bool {
        let depth = -p[2];
        if !(depth.is_finite() && depth > 0.0) {
            return false;
        }
        let u = self.cx + self.fx * p[0] / depth;
        let v = self.cy - self.fy * p[1] / depth;
        (0.0..f64::from(self.width)).contains(&u) && (0.0..f64::from(self.height)).contains(&v)
    }
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
    /// Uniform scale of the catalog's mesh and part boxes about the object
    /// frame's origin; 1 is the catalog's size. The planner writes 1 (the
    /// lever that resized objects was measured and deleted); Blender and
    /// the part labels honour another value in a plan file, at which size
    /// `pose` places the object.
    #[serde(default = "unit_scale")]
    pub scale: f64,
    /// Per-axis factors of the object frame's X, Y, Z on top of `scale`
    /// (`[randomize.proportions]`: the object's proportions, its size kept,
    /// their product 1); absent means [1, 1, 1].
    #[serde(default = "unit_proportions", skip_serializing_if = "is_unit")]
    pub proportions: [f64; 3],
}

fn unit_scale() -> f64 {
    1.0
}

fn unit_proportions() -> [f64; 3] {
    [1.0; 3]
}

fn is_unit(p: &[f64; 3]) -> bool {
    *p == [1.0; 3]
}

impl ObjectPlacement {
    /// The factor each axis of the catalog's object frame is scaled by:
    /// `scale` times `proportions`. Blender, the part labels and the
    /// planner's geometry all read this one rule.
    pub fn axis_scale(&self) -> [f64; 3] {
        self.proportions.map(|p| p * self.scale)
    }
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

    /// Leading frames in which the target point is outside the wrist
    /// camera's image: the lead-in of a `from_ground` reach, where the camera
    /// faces the floor, which the paper trims at inference time. 0 when the
    /// first frame sees the target, and when no frame does (nothing to
    /// anchor a trim on).
    pub fn lead_in_frames(&self) -> usize {
        self.frames
            .iter()
            .position(|f| self.intrinsics.sees(f.camera.to_local(self.target)))
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HALF_TURN_ABOUT_X: [f64; 4] = [0.0, 1.0, 0.0, 0.0];

    fn lens() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 100,
            height: 80,
            fx: 100.0,
            fy: 100.0,
            cx: 50.0,
            cy: 40.0,
            fov_x_deg: 53.1,
            fov_y_deg: 43.6,
            clip_near: 0.01,
            clip_far: 10.0,
        }
    }

    fn pose(position: [f64; 3], rotation_wxyz: [f64; 4]) -> Pose {
        Pose {
            position,
            rotation_wxyz,
        }
    }

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn to_local_undoes_the_pose() {
        let at_origin = pose([0.0; 3], [1.0, 0.0, 0.0, 0.0]);
        assert!(close(at_origin.to_local([1.0, 2.0, 3.0]), [1.0, 2.0, 3.0]));
        let moved = pose([1.0, 1.0, 1.0], [1.0, 0.0, 0.0, 0.0]);
        assert!(close(moved.to_local([1.0, 2.0, 3.0]), [0.0, 1.0, 2.0]));
        // A quarter turn about Z maps the camera's +X onto the world's +Y,
        // so the world's +Y is the camera's +X.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let turned = pose([0.0; 3], [s, 0.0, 0.0, s]);
        assert!(close(turned.to_local([0.0, 1.0, 0.0]), [1.0, 0.0, 0.0]));
        // Half a turn about X: the camera looks along the world's +Z.
        let up = pose([0.0; 3], HALF_TURN_ABOUT_X);
        assert!(close(up.to_local([0.0, 0.0, 2.0]), [0.0, 0.0, -2.0]));
        // An unnormalised quaternion is the same rotation.
        let scaled = pose([0.0; 3], [2.0 * s, 0.0, 0.0, 2.0 * s]);
        assert!(close(scaled.to_local([0.0, 1.0, 0.0]), [1.0, 0.0, 0.0]));
    }

    #[test]
    fn sees_only_points_in_front_and_inside_the_image() {
        let k = lens();
        assert!(k.sees([0.0, 0.0, -1.0]));
        assert!(!k.sees([0.0, 0.0, 1.0]), "behind the lens");
        assert!(!k.sees([0.0, 0.0, 0.0]), "at the lens");
        assert!(k.sees([0.49, 0.0, -1.0]) && !k.sees([0.51, 0.0, -1.0]));
        assert!(k.sees([0.0, 0.39, -1.0]) && !k.sees([0.0, 0.41, -1.0]));
        assert!(!k.sees([f64::NAN, 0.0, -1.0]) && !k.sees([0.0, 0.0, f64::NAN]));
    }

    fn plan(cameras: &[Pose]) -> SequencePlan {
        SequencePlan {
            schema_version: PLAN_SCHEMA_VERSION,
            dataset_seed: 0,
            key: SequenceKey {
                object: "o".into(),
                part: "p".into(),
                index: 0,
                condition: Condition::FromGround,
            },
            stream_seed: 0,
            category: "c".into(),
            grasp_type: GraspType::MediumWrap,
            preshape: Preshape::Power,
            part_index: 0,
            fps: 1.0,
            duration_s: cameras.len() as f64,
            intrinsics: lens(),
            object: ObjectPlacement {
                pose: pose([0.0; 3], [1.0, 0.0, 0.0, 0.0]),
                yaw_deg: 0.0,
                upside_down: false,
                on_table_border: false,
                scale: 1.0,
                proportions: [1.0; 3],
            },
            target: [0.0, 0.0, 0.0],
            other_end: [0.0, 0.0, 0.0],
            frames: cameras
                .iter()
                .enumerate()
                .map(|(i, c)| FramePlan {
                    index: i as u32,
                    time_s: i as f64,
                    camera: *c,
                    class: Class::from(Preshape::Power),
                    head_camera: None,
                })
                .collect(),
            sampled: BTreeMap::new(),
            appearance: None,
            distractors: Vec::new(),
        }
    }

    #[test]
    fn lead_in_counts_the_frames_before_the_target_enters_the_view() {
        // The target is at the origin. Looking down from above sees it;
        // looking down from one metre to the side (at the floor) does not,
        // nor does looking up from below.
        let above = pose([0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0]);
        let beside = pose([1.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0]);
        let below = pose([0.0, 0.0, -1.0], [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(plan(&[beside, below, above, beside]).lead_in_frames(), 2);
        assert_eq!(plan(&[above, beside]).lead_in_frames(), 0);
        assert_eq!(plan(&[beside, below]).lead_in_frames(), 0, "never seen");
        assert_eq!(plan(&[]).lead_in_frames(), 0, "no frames");
        let looking_up = pose([0.0, 0.0, -1.0], HALF_TURN_ABOUT_X);
        assert_eq!(plan(&[below, looking_up]).lead_in_frames(), 1);
    }
}
