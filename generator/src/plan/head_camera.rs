//! The egocentric (head-mounted) camera: an optional second view of every
//! sequence, for the paper's eye-in-hand versus egocentric comparison.
//!
//! The user stands (or, in the `seated` condition, sits) on the table's -X
//! side. The eyes are `behind_edge_m` behind the table's near edge, offset
//! `lateral_m` along +Y from the object (a right hand reaches objects in
//! front of the right shoulder, so the head sits a little to the left), at
//! a standing or seated eye height above the floor.
//!
//! The head is static during a sequence and fixates the object: people look
//! at the object they are about to grasp before and during the reach, and a
//! head-mounted camera follows the head, not the eyes. The aim is the
//! object's bounding-sphere centre, off by a small angle drawn uniformly in
//! a cone of half-angle `aim_jitter_deg`, with a small roll about the view
//! axis. Every value comes from the sequence's own `head_camera` sub-stream,
//! so turning the camera on changes no other value of the plan.
//!
//! The right shoulder sits at a fixed offset from the eyes
//! ([`SHOULDER_FROM_EYE`]); for every frame, [`elbow`] bends a two-link arm
//! from it to the wrist camera, so the head view can draw the upper arm and
//! the forearm (the wrist view's forearm runs along its own camera axis).

use super::scene::{uniform, SceneConfig};
use super::wrist::{look_at, roll, to_wxyz};
use crate::config::error::{ConfigError, Result};
use grasp_schema::plan::Pose;
use grasp_schema::Condition;
use nalgebra::{Unit, UnitQuaternion, Vector3};
use rand::Rng;
use serde::{Deserialize, Serialize};
use serde_json::json;

/// The right shoulder relative to the eyes (world axes: slightly behind,
/// to the right, below), metres; adult averages.
pub const SHOULDER_FROM_EYE: [f64; 3] = [-0.05, -0.18, -0.22];

/// Shoulder-to-elbow and elbow-to-wrist-camera lengths, metres.
pub const UPPER_ARM_M: f64 = 0.30;
pub const FOREARM_M: f64 = 0.27;

/// The elbow of a two-link arm from `shoulder` to `wrist`, bent down and a
/// little outwards (to the right, -Y) as a relaxed arm is. Out of reach,
/// the arm is straight towards the wrist.
pub fn elbow(shoulder: &Vector3<f64>, wrist: &Vector3<f64>) -> Vector3<f64> {
    let (l1, l2) = (UPPER_ARM_M, FOREARM_M);
    let d = wrist - shoulder;
    let u = d.try_normalize(1e-9).unwrap_or(-Vector3::z());
    let reach = d.norm().clamp((l1 - l2).abs(), l1 + l2);
    // Law of cosines: the elbow circle's centre along u and its radius.
    let along = (l1 * l1 - l2 * l2 + reach * reach) / (2.0 * reach);
    let radius = (l1 * l1 - along * along).max(0.0).sqrt();
    let bend = Vector3::new(0.0, -0.3, -1.0);
    let n = (bend - u * u.dot(&bend))
        .try_normalize(1e-9)
        .unwrap_or_else(|| u.cross(&Vector3::x()).normalize());
    shoulder + u * along + n * radius
}

/// `[plan.head_camera]`: off unless `enabled = true`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadCameraConfig {
    pub enabled: bool,
    /// Horizontal distance of the eyes behind the table's near edge, metres.
    pub behind_edge_m: [f64; 2],
    /// Offset of the eyes from the object along world Y, metres.
    pub lateral_m: [f64; 2],
    /// Eye height above the floor of a standing user, metres.
    pub standing_eye_height_m: [f64; 2],
    /// Eye height above the floor in the `seated` condition, metres.
    pub seated_eye_height_m: [f64; 2],
    /// Half-angle of the cone the view direction is drawn in around the
    /// object's centre, degrees.
    pub aim_jitter_deg: f64,
    /// Roll about the view axis is uniform in +- this, degrees.
    pub roll_jitter_deg: f64,
}

impl Default for HeadCameraConfig {
    fn default() -> Self {
        HeadCameraConfig {
            enabled: false,
            behind_edge_m: [0.15, 0.3],
            lateral_m: [0.0, 0.2],
            standing_eye_height_m: [1.5, 1.7],
            seated_eye_height_m: [1.1, 1.25],
            aim_jitter_deg: 3.0,
            roll_jitter_deg: 2.0,
        }
    }
}

impl HeadCameraConfig {
    // Negated comparisons: a NaN must fail these checks.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn validate(&self, scene: &SceneConfig) -> Result<()> {
        for (name, r) in [
            ("behind_edge_m", self.behind_edge_m),
            ("lateral_m", self.lateral_m),
            ("standing_eye_height_m", self.standing_eye_height_m),
            ("seated_eye_height_m", self.seated_eye_height_m),
        ] {
            if !(r[0].is_finite() && r[1].is_finite() && r[0] <= r[1]) {
                return Err(ConfigError::rule(
                    format!("plan.head_camera.{name}"),
                    format!("must be a range [min, max], got {r:?}"),
                ));
            }
        }
        if !(self.behind_edge_m[0] >= 0.0) {
            return Err(ConfigError::rule(
                "plan.head_camera.behind_edge_m",
                format!(
                    "must be >= 0 (the user cannot stand in the table), got {:?}",
                    self.behind_edge_m
                ),
            ));
        }
        // The eyes must fit the scene only when the camera is used: a scaled
        // scene (tests plan millimetre tables) need not rescale a camera
        // that stays off.
        let heights = if self.enabled {
            vec![
                ("standing_eye_height_m", self.standing_eye_height_m),
                ("seated_eye_height_m", self.seated_eye_height_m),
            ]
        } else {
            Vec::new()
        };
        for (name, r) in heights {
            if !(r[0] > scene.table_height && r[1] < scene.room_size[2]) {
                return Err(ConfigError::rule(
                    format!("plan.head_camera.{name}"),
                    format!(
                        "{r:?} must lie between the table top ({}) and the ceiling ({})",
                        scene.table_height, scene.room_size[2]
                    ),
                ));
            }
        }
        for (name, v) in [
            ("aim_jitter_deg", self.aim_jitter_deg),
            ("roll_jitter_deg", self.roll_jitter_deg),
        ] {
            if !((0.0..45.0).contains(&v)) {
                return Err(ConfigError::rule(
                    format!("plan.head_camera.{name}"),
                    format!("must be in [0, 45), got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// A sampled head camera.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadCamera {
    pub eye: Vector3<f64>,
    pub rotation: UnitQuaternion<f64>,
    pub seated: bool,
    /// Angle between the view direction and the object's centre, radians.
    pub aim_offset: f64,
    pub roll: f64,
}

impl HeadCamera {
    /// The right shoulder, world.
    pub fn shoulder(&self) -> Vector3<f64> {
        self.eye + Vector3::from(SHOULDER_FROM_EYE)
    }

    pub fn pose(&self) -> Pose {
        Pose {
            position: self.eye.into(),
            rotation_wxyz: to_wxyz(&self.rotation),
        }
    }

    /// The values recorded in the plan's `sampled` map.
    pub fn sampled(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![
            ("head_eye", json!(self.eye.as_slice())),
            ("head_shoulder", json!(self.shoulder().as_slice())),
            (
                "head_posture",
                json!(if self.seated { "seated" } else { "standing" }),
            ),
            ("head_aim_offset_deg", json!(self.aim_offset.to_degrees())),
            ("head_roll_deg", json!(self.roll.to_degrees())),
        ]
    }
}

/// Samples the head camera of one sequence looking at `object_center`
/// (world) with the object's origin at `object_xy`.
pub fn sample<R: Rng>(
    cfg: &HeadCameraConfig,
    scene: &SceneConfig,
    condition: Condition,
    object_xy: [f64; 2],
    object_center: &Vector3<f64>,
    rng: &mut R,
) -> HeadCamera {
    let seated = condition == Condition::Seated;
    let height = if seated {
        cfg.seated_eye_height_m
    } else {
        cfg.standing_eye_height_m
    };
    let eye = Vector3::new(
        scene.near_edge_x() - uniform(rng, cfg.behind_edge_m[0], cfg.behind_edge_m[1]),
        object_xy[1] + uniform(rng, cfg.lateral_m[0], cfg.lateral_m[1]),
        uniform(rng, height[0], height[1]),
    );
    // Uniform direction in the cone: cos(offset) uniform in [cos(max), 1].
    let max = cfg.aim_jitter_deg.to_radians();
    let aim_offset = uniform(rng, max.cos(), 1.0).clamp(-1.0, 1.0).acos();
    let azimuth = uniform(rng, 0.0, std::f64::consts::TAU);
    let roll_angle = uniform(rng, -cfg.roll_jitter_deg, cfg.roll_jitter_deg).to_radians();
    let fixate = look_at(&(object_center - eye), &Vector3::z(), &Vector3::x());
    // Tilt about an axis perpendicular to the view (camera frame), then roll.
    let axis = Unit::new_normalize(Vector3::new(azimuth.cos(), azimuth.sin(), 0.0));
    let tilted = fixate * UnitQuaternion::from_axis_angle(&axis, aim_offset);
    HeadCamera {
        eye,
        rotation: roll(&tilted, roll_angle),
        seated,
        aim_offset,
        roll: roll_angle,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::wrist::view_direction;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn looks_at_the_object_within_the_jitter_cone() {
        let cfg = HeadCameraConfig {
            enabled: true,
            ..Default::default()
        };
        let scene = SceneConfig::default();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut largest: f64 = 0.0;
        for i in 0..2000 {
            let center = Vector3::new(-0.1 + 0.0001 * i as f64, 0.3, 0.82);
            let cond = if i % 2 == 0 {
                Condition::Default
            } else {
                Condition::Seated
            };
            let h = sample(&cfg, &scene, cond, [center.x, center.y], &center, &mut rng);
            let angle = view_direction(&h.rotation).angle(&(center - h.eye));
            assert!((angle - h.aim_offset).abs() < 1e-9, "{angle} {h:?}");
            assert!(angle <= cfg.aim_jitter_deg.to_radians() + 1e-12);
            largest = largest.max(angle);
            // Behind the near edge, at the posture's eye height.
            assert!(h.eye.x <= scene.near_edge_x() - cfg.behind_edge_m[0] + 1e-12);
            let r = if cond == Condition::Seated {
                cfg.seated_eye_height_m
            } else {
                cfg.standing_eye_height_m
            };
            assert!(h.eye.z >= r[0] && h.eye.z <= r[1]);
            assert!((h.rotation.quaternion().norm() - 1.0).abs() < 1e-12);
            // The image's up stays close to world up (roll jitter is small).
            let up = h.rotation * Vector3::y();
            assert!(up.z > 0.0);
        }
        // The cone is used, not just its axis.
        assert!(largest > 0.9 * cfg.aim_jitter_deg.to_radians());
    }

    #[test]
    fn the_elbow_joins_links_of_the_arm_lengths_and_bends_down() {
        let shoulder = Vector3::new(-0.6, -0.2, 1.3);
        for wrist in [
            Vector3::new(-0.3, -0.1, 0.95),
            Vector3::new(-0.2, 0.1, 1.2),
            Vector3::new(-0.55, -0.25, 1.0),
        ] {
            let e = elbow(&shoulder, &wrist);
            assert!(((e - shoulder).norm() - UPPER_ARM_M).abs() < 1e-9);
            assert!(((wrist - e).norm() - FOREARM_M).abs() < 1e-9);
            // Below the shoulder-wrist line.
            let t = (e - shoulder).dot(&(wrist - shoulder)) / (wrist - shoulder).norm_squared();
            assert!(e.z < shoulder.z + t * (wrist.z - shoulder.z));
        }
        // Out of reach: straight, the upper arm pointing at the wrist.
        let far = Vector3::new(0.4, -0.2, 1.3);
        let e = elbow(&shoulder, &far);
        assert!((e - (shoulder + Vector3::x() * UPPER_ARM_M)).norm() < 1e-9);
        // Degenerate: the wrist on the shoulder gives a finite point.
        assert!(elbow(&shoulder, &shoulder).iter().all(|x| x.is_finite()));
    }

    #[test]
    fn zero_jitter_fixates_exactly() {
        let cfg = HeadCameraConfig {
            aim_jitter_deg: 0.0,
            roll_jitter_deg: 0.0,
            ..Default::default()
        };
        let center = Vector3::new(0.0, 0.0, 0.8);
        let h = sample(
            &cfg,
            &SceneConfig::default(),
            Condition::Fast,
            [0.0, 0.0],
            &center,
            &mut ChaCha8Rng::seed_from_u64(1),
        );
        let angle = view_direction(&h.rotation).angle(&(center - h.eye));
        assert!(angle < 1e-9, "{angle}");
        assert_eq!(h.roll, 0.0);
    }

    #[test]
    fn bad_ranges_name_the_field() {
        let scene = SceneConfig::default();
        let mut bad = HeadCameraConfig {
            enabled: true,
            seated_eye_height_m: [0.5, 0.7],
            ..Default::default()
        };
        let e = bad.validate(&scene).unwrap_err().to_string();
        assert!(e.contains("plan.head_camera.seated_eye_height_m"), "{e}");
        // Eyes below the table only matter when the camera is on.
        bad.enabled = false;
        bad.validate(&scene).unwrap();
        let bad = HeadCameraConfig {
            lateral_m: [0.3, 0.1],
            ..Default::default()
        };
        let e = bad.validate(&scene).unwrap_err().to_string();
        assert!(e.contains("plan.head_camera.lateral_m"), "{e}");
        HeadCameraConfig::default().validate(&scene).unwrap();
    }
}
