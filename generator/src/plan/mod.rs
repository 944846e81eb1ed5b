//! Reach planning: turns (dataset seed, object, part, index, condition) into
//! a [`SequencePlan`](grasp_schema::SequencePlan), with nothing left to
//! chance at render time. See `docs/planning.md`.

pub mod budget;
pub mod camera;
pub mod check;
pub mod conditions;
pub mod distractors;
pub mod error;
pub mod head_camera;
pub mod jsonl;
mod planner;
pub mod plot_paths;
pub mod scene;
pub mod selection;
pub mod shake;
pub mod source;
pub mod trajectory;
pub mod validity;
pub mod wrist;

pub use camera::CameraConfig;
pub use conditions::ConditionsConfig;
pub use error::PlanError;
pub use head_camera::HeadCameraConfig;
pub use jsonl::read_jsonl;
pub use planner::{sequence_keys, ObjectGeometry, Planner};
pub use scene::SceneConfig;
pub use shake::ShakeConfig;
pub use source::{PlanSource, PlannedKey, PlannerSource};
pub use trajectory::TrajectoryConfig;
pub use validity::ValidityConfig;

/// [`read_jsonl`], where it was before `grasp-gen plan` moved into the
/// binary.
pub mod cli {
    pub use super::jsonl::read_jsonl;
}

use crate::config::error::{ConfigError, Result};
use grasp_schema::Condition;
use serde::{Deserialize, Serialize};

/// What to generate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DatasetConfig {
    /// Dataset seed: every sequence's random stream derives from it.
    pub seed: u64,
    /// Sequences per (object, part) pair and condition (the paper's 47).
    pub sequences_per_pair: u32,
    /// Conditions to generate, in order.
    pub conditions: Vec<Condition>,
    /// Only these object ids (all when absent).
    pub objects: Option<Vec<String>>,
    /// Only these parts, as `part` or `object/part` (all when absent).
    pub parts: Option<Vec<String>>,
    /// A test world that training must never draw from (`"reach"` in
    /// configs/test-world-reach.toml): recorded in every plan as
    /// `sampled.held_out`; grasp-train refuses such sequences for training
    /// and validation, as it refuses `unseen_look` and non-studio worlds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<String>,
}

impl Default for DatasetConfig {
    fn default() -> Self {
        DatasetConfig {
            seed: 2022,
            sequences_per_pair: 47,
            conditions: vec![Condition::Default],
            objects: None,
            parts: None,
            held_out: None,
        }
    }
}

/// Scene, camera and trajectory parameters.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlanConfig {
    /// Room, table and placement (world frame: metres, Z up, floor z = 0).
    pub scene: SceneConfig,
    /// Lens preset, image size and start region.
    pub camera: CameraConfig,
    /// Duration, frame rate, labels, wrist rotations, resampling bound.
    pub trajectory: TrajectoryConfig,
    /// The validity rule's tolerance and batching.
    pub validity: ValidityConfig,
    /// Settings of the fast, seated and from_ground conditions.
    pub conditions: ConditionsConfig,
    /// The optional egocentric (head-mounted) camera; off by default.
    pub head_camera: HeadCameraConfig,
    /// Handheld shake over the reach; off by default (the camera world).
    pub shake: ShakeConfig,
}

impl PlanConfig {
    /// Checks every value, naming the offending field.
    // Negated comparisons: a NaN must fail these checks.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn validate(&self) -> Result<()> {
        self.scene.validate()?;
        self.camera.validate()?;
        self.trajectory.validate()?;
        self.conditions.validate()?;
        self.head_camera.validate(&self.scene)?;
        self.shake.validate()?;
        for c in Condition::ALL {
            let d = self.conditions.duration_s(c, self.trajectory.duration_s);
            self.trajectory.frame_count(d)?;
            if !(self.trajectory.no_grasp_tail_s < d) {
                return Err(ConfigError::rule(
                    "plan.trajectory.no_grasp_tail_s",
                    format!(
                        "({}) must be shorter than the {c} sequences ({d} s)",
                        self.trajectory.no_grasp_tail_s
                    ),
                ));
            }
        }
        if !(self.validity.mesh_tolerance_m >= 0.0) {
            return Err(ConfigError::rule(
                "plan.validity.mesh_tolerance_m",
                "must be >= 0",
            ));
        }
        Ok(())
    }
}
