//! Test-condition presets and the camera path each one draws.
//!
//! - `default`, `background` and `unseen_look`: a straight minimum-jerk
//!   reach from a start on the vertical start plane (the other two differ
//!   only in appearance);
//! - `fast`: the same start distances, completed in `fast.duration_s`;
//! - `seated`: a lower, closer start and a curved (quadratic Bezier) path
//!   that rises and then comes down onto the target;
//! - `from_ground`: the arm hangs along the body with the camera towards the
//!   floor, rises, and approaches through a via-point with the closed-form
//!   minimum-jerk via-point solution (continuous velocity and acceleration).

use super::camera::StartRegion;
use super::error::{PlanError, Result};
use super::scene::{uniform, SceneConfig};
use super::trajectory::{Path, ViaPath};
use grasp_schema::Condition;
use nalgebra::Vector3;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Settings of the non-default conditions.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConditionsConfig {
    pub fast: FastPreset,
    pub seated: SeatedPreset,
    pub from_ground: FromGroundPreset,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FastPreset {
    /// Sequence length, seconds (the paper's "different velocity": 1.5 s).
    pub duration_s: f64,
}

impl Default for FastPreset {
    fn default() -> Self {
        FastPreset { duration_s: 1.5 }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SeatedPreset {
    /// Sequence length, seconds (the paper's seated grasps take 1.5 s).
    pub duration_s: f64,
    /// Scales the camera's start distances (plane distance and accepted
    /// distance range): a seated user starts closer.
    pub distance_scale: f64,
    /// Scales the start heights above the table: a seated user starts lower.
    pub height_scale: f64,
    /// Height of the Bezier control point above the start-target chord, metres.
    pub lift_m: [f64; 2],
    /// Where along the chord the control point sits (0 = start, 1 = target).
    pub control_at: [f64; 2],
}

impl Default for SeatedPreset {
    fn default() -> Self {
        SeatedPreset {
            duration_s: 1.5,
            distance_scale: 0.75,
            height_scale: 0.35,
            lift_m: [0.08, 0.2],
            control_at: [0.3, 0.6],
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FromGroundPreset {
    /// Sequence length, seconds: the rise plus the approach.
    pub duration_s: f64,
    /// Horizontal distance of the hanging hand behind the table's near edge, metres.
    pub hang_behind_edge_m: [f64; 2],
    /// Lateral offset of the hanging (right) hand from the target, metres (world Y).
    pub hang_lateral_m: [f64; 2],
    /// Height of the hanging wrist camera above the floor, metres.
    pub hang_height_m: [f64; 2],
    /// Normalised time at which the path passes the via-point (the usual
    /// start, with the object in view).
    pub via_time: [f64; 2],
}

impl Default for FromGroundPreset {
    fn default() -> Self {
        FromGroundPreset {
            duration_s: 4.0,
            hang_behind_edge_m: [0.15, 0.3],
            hang_lateral_m: [-0.35, -0.15],
            hang_height_m: [0.65, 0.85],
            via_time: [0.35, 0.5],
        }
    }
}

impl ConditionsConfig {
    /// Sequence length of a condition.
    pub fn duration_s(&self, condition: Condition, default_s: f64) -> f64 {
        match condition {
            Condition::Default | Condition::Background | Condition::UnseenLook => default_s,
            Condition::Fast => self.fast.duration_s,
            Condition::Seated => self.seated.duration_s,
            Condition::FromGround => self.from_ground.duration_s,
        }
    }

    pub fn validate(&self) -> crate::config::error::Result<()> {
        for (name, d) in [
            ("fast", self.fast.duration_s),
            ("seated", self.seated.duration_s),
            ("from_ground", self.from_ground.duration_s),
        ] {
            if !(d.is_finite() && d > 0.0) {
                return Err(crate::config::error::ConfigError::rule(
                    format!("plan.conditions.{name}.duration_s"),
                    format!("must be positive, got {d}"),
                ));
            }
        }
        let s = &self.seated;
        if !(s.distance_scale > 0.0 && s.height_scale > 0.0) {
            return Err(crate::config::error::ConfigError::rule(
                "plan.conditions.seated.distance_scale",
                "and height_scale must be positive",
            ));
        }
        let g = &self.from_ground;
        if !(g.via_time[0] > 0.0 && g.via_time[1] < 1.0 && g.via_time[0] <= g.via_time[1]) {
            return Err(crate::config::error::ConfigError::rule(
                "plan.conditions.from_ground.via_time",
                format!("must be a range inside (0, 1), got {:?}", g.via_time),
            ));
        }
        Ok(())
    }
}

/// A sampled camera path with what the planner needs to check and orient it.
#[derive(Debug, Clone)]
pub struct PathSample {
    pub path: Path,
    /// Point from which the object must be in view (the start, or the
    /// via-point when the start faces the floor).
    pub view_point: Vector3<f64>,
    /// Distance from `view_point` to the target (checked against the range).
    pub view_distance: f64,
    /// Normalised time the approach (and the wrist schedule) starts.
    pub approach_tau: f64,
    /// The rise from the floor-facing start ends at this normalised time.
    pub rise_until: Option<f64>,
    /// Named sampled values, recorded in the plan.
    pub sampled: Vec<(&'static str, serde_json::Value)>,
}

/// Samples a start on the vertical start plane in front of `target`.
pub fn sample_start<R: Rng>(
    region: &StartRegion,
    scene: &SceneConfig,
    target: &Vector3<f64>,
    distance_scale: f64,
    height_scale: f64,
    rng: &mut R,
) -> Vector3<f64> {
    let d = uniform(
        rng,
        region.plane_distance_m[0] * distance_scale,
        region.plane_distance_m[1] * distance_scale,
    );
    let l = uniform(rng, region.lateral_m[0], region.lateral_m[1]);
    let h = uniform(
        rng,
        region.height_m[0] * height_scale,
        region.height_m[1] * height_scale,
    );
    Vector3::new(target.x - d, target.y + l, scene.table_height + h)
}

/// The end point: `standoff` short of the target along the final approach
/// direction `from -> target`. None when `from` is within the standoff.
pub fn end_point(
    from: &Vector3<f64>,
    target: &Vector3<f64>,
    standoff: f64,
) -> Option<Vector3<f64>> {
    let d = target - from;
    let len = d.norm();
    if len <= standoff || len < 1e-9 || len.is_nan() {
        return None;
    }
    Some(target - d * (standoff / len))
}

/// The straight approach from `start`, with a clear error when it is
/// degenerate (start on or within the standoff of the target).
pub fn straight_approach(
    start: &Vector3<f64>,
    target: &Vector3<f64>,
    standoff: f64,
) -> Result<Path> {
    let dist = (target - start).norm();
    if dist < 1e-9 || dist.is_nan() {
        return Err(PlanError::DegenerateApproach(format!(
            "the start coincides with the target {target:?}: no approach direction"
        )));
    }
    let end = end_point(start, target, standoff).ok_or_else(|| {
        PlanError::DegenerateApproach(format!(
            "the start is {dist:.4} m from the target, within the {standoff} m stand-off"
        ))
    })?;
    Ok(Path::Straight { start: *start, end })
}

/// Context shared by the path samplers.
pub struct PathContext<'a> {
    pub condition: Condition,
    pub presets: &'a ConditionsConfig,
    pub region: &'a StartRegion,
    pub scene: &'a SceneConfig,
    pub standoff: f64,
    pub curve_segments: usize,
}

/// Samples the camera path of one candidate. `None` when the sampled start
/// cannot form a path (it is within the standoff of the target).
pub fn sample_path<R: Rng>(
    ctx: &PathContext<'_>,
    target: &Vector3<f64>,
    rng: &mut R,
) -> Option<PathSample> {
    use serde_json::json;
    match ctx.condition {
        Condition::Default | Condition::Background | Condition::UnseenLook | Condition::Fast => {
            let start = sample_start(ctx.region, ctx.scene, target, 1.0, 1.0, rng);
            let path = straight_approach(&start, target, ctx.standoff).ok()?;
            Some(PathSample {
                path,
                view_point: start,
                view_distance: (target - start).norm(),
                approach_tau: 0.0,
                rise_until: None,
                sampled: vec![("start", json!(start.as_slice()))],
            })
        }
        Condition::Seated => {
            let p = &ctx.presets.seated;
            let start = sample_start(
                ctx.region,
                ctx.scene,
                target,
                p.distance_scale,
                p.height_scale,
                rng,
            );
            let at = uniform(rng, p.control_at[0], p.control_at[1]);
            let lift = uniform(rng, p.lift_m[0], p.lift_m[1]);
            let control = start + (target - start) * at + Vector3::z() * lift;
            let end = end_point(&control, target, ctx.standoff)?;
            (target - start).norm().gt(&ctx.standoff).then_some(())?;
            Some(PathSample {
                path: Path::Curved {
                    start,
                    control,
                    end,
                },
                view_point: start,
                view_distance: (target - start).norm(),
                approach_tau: 0.0,
                rise_until: None,
                sampled: vec![
                    ("start", json!(start.as_slice())),
                    ("curve_control", json!(control.as_slice())),
                    ("curve_control_at", json!(at)),
                    ("curve_lift_m", json!(lift)),
                ],
            })
        }
        Condition::FromGround => {
            let p = &ctx.presets.from_ground;
            let via = sample_start(ctx.region, ctx.scene, target, 1.0, 1.0, rng);
            let hang = Vector3::new(
                ctx.scene.near_edge_x()
                    - uniform(rng, p.hang_behind_edge_m[0], p.hang_behind_edge_m[1]),
                target.y + uniform(rng, p.hang_lateral_m[0], p.hang_lateral_m[1]),
                uniform(rng, p.hang_height_m[0], p.hang_height_m[1]),
            );
            let tau1 = uniform(rng, p.via_time[0], p.via_time[1]);
            let end = end_point(&via, target, ctx.standoff)?;
            Some(PathSample {
                path: Path::Via(ViaPath::new(hang, via, end, tau1)),
                view_point: via,
                view_distance: (target - via).norm(),
                approach_tau: tau1,
                rise_until: Some(tau1),
                sampled: vec![
                    ("start", json!(hang.as_slice())),
                    ("via_point", json!(via.as_slice())),
                    ("via_time", json!(tau1)),
                ],
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn start_on_the_target_is_a_clear_error() {
        let t = Vector3::new(0.1, 0.2, 0.8);
        let err = straight_approach(&t, &t, 0.12).unwrap_err().to_string();
        assert!(err.contains("coincides with the target"), "{err}");
        let near = t - Vector3::new(0.05, 0.0, 0.0);
        let err = straight_approach(&near, &t, 0.12).unwrap_err().to_string();
        assert!(err.contains("stand-off"), "{err}");
        assert!(straight_approach(&near, &t, 0.0).is_ok());
    }
}
