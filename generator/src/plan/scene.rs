//! The scene the reach happens in: room, table, object placement.
//!
//! World frame: right-handed, metres, Z up, the floor at z = 0. The room is
//! an axis-aligned box centred on the world origin. The user stands on the
//! table's -X side and reaches towards +X, so "forward" is +X and the near
//! table edge is at `table_center.x - table_size.x / 2`.

use crate::catalog::{GraspPart, UpsideDown};
use crate::config::error::{ConfigError, Result};
use nalgebra::{UnitQuaternion, Vector3};
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Room, table and placement geometry. The renderer builds the Blender room
/// and table from this same struct.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneConfig {
    /// Interior size of the room (x, y, height), metres. The room is centred
    /// on the world origin; its floor is at z = 0 and its ceiling at z = height.
    pub room_size: [f64; 3],
    /// Centre of the table top in the world (x, y), metres.
    pub table_center: [f64; 2],
    /// Size of the table top (x = depth along the reach, y = width), metres.
    pub table_size: [f64; 2],
    /// Height of the table's top surface above the floor, metres.
    pub table_height: f64,
    /// Thickness of the table top slab, metres. The slab (top surface down
    /// to top minus thickness) is an obstacle in the validity check.
    pub table_thickness: f64,
    /// Centre of the object placement area on the table top, relative to
    /// `table_center` (x, y), metres.
    pub placement_center: [f64; 2],
    /// Size of the placement area (x, y), metres. The object's origin (the
    /// centre of its footprint) is sampled uniformly in it.
    pub placement_size: [f64; 2],
    /// For parts tagged `table_border`: distance from the table's near edge
    /// (the user's side, -X) to the object's origin, metres. The object's y
    /// is still sampled over the placement area.
    pub border_inset: f64,
    /// For `table_border` parts, the yaw turns the grasped part towards the
    /// user (so a plate rim or a hammer handle overhangs the edge), plus or
    /// minus this many degrees. `None` samples the yaw uniformly as the
    /// authors did.
    pub border_yaw_jitter_deg: Option<f64>,
    /// Probability of an upside-down placement for parts that allow it.
    pub upside_down_probability: f64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig {
            room_size: [6.0, 6.0, 3.0],
            table_center: [0.0, 0.0],
            table_size: [0.8, 1.4],
            table_height: 0.75,
            table_thickness: 0.04,
            placement_center: [-0.1, 0.0],
            placement_size: [0.4, 0.8],
            border_inset: 0.06,
            border_yaw_jitter_deg: Some(40.0),
            upside_down_probability: 0.5,
        }
    }
}

impl SceneConfig {
    /// x of the table's near edge (the user's side).
    pub fn near_edge_x(&self) -> f64 {
        self.table_center[0] - self.table_size[0] / 2.0
    }

    /// Placement area as (min, max) corners in world x, y.
    pub fn placement_bounds(&self) -> ([f64; 2], [f64; 2]) {
        let c = [
            self.table_center[0] + self.placement_center[0],
            self.table_center[1] + self.placement_center[1],
        ];
        let h = [self.placement_size[0] / 2.0, self.placement_size[1] / 2.0];
        ([c[0] - h[0], c[1] - h[1]], [c[0] + h[0], c[1] + h[1]])
    }

    /// The table-top slab as an axis-aligned box (min, max corners).
    pub fn table_slab(&self) -> ([f64; 3], [f64; 3]) {
        let [cx, cy] = self.table_center;
        let [sx, sy] = self.table_size;
        (
            [
                cx - sx / 2.0,
                cy - sy / 2.0,
                self.table_height - self.table_thickness,
            ],
            [cx + sx / 2.0, cy + sy / 2.0, self.table_height],
        )
    }

    // Negated comparisons: a NaN must fail these checks.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f64| -> Result<()> {
            if !(v.is_finite() && v > 0.0) {
                return Err(ConfigError::rule(
                    format!("plan.scene.{name}"),
                    format!("must be positive, got {v}"),
                ));
            }
            Ok(())
        };
        for (i, v) in self.room_size.iter().enumerate() {
            pos(&format!("room_size[{i}]"), *v)?;
        }
        pos("table_size[0]", self.table_size[0])?;
        pos("table_size[1]", self.table_size[1])?;
        pos("table_height", self.table_height)?;
        pos("table_thickness", self.table_thickness)?;
        if !(self.table_height < self.room_size[2]) {
            return Err(ConfigError::rule(
                "plan.scene.table_height",
                format!(
                    "({}) must be below the ceiling ({})",
                    self.table_height, self.room_size[2]
                ),
            ));
        }
        for (i, v) in self.placement_size.iter().enumerate() {
            if !(v.is_finite() && *v >= 0.0) {
                return Err(ConfigError::rule(
                    format!("plan.scene.placement_size[{i}]"),
                    format!("must be >= 0, got {v}"),
                ));
            }
        }
        if !((0.0..=1.0).contains(&self.upside_down_probability)) {
            return Err(ConfigError::rule(
                "plan.scene.upside_down_probability",
                format!("must be in [0, 1], got {}", self.upside_down_probability),
            ));
        }
        Ok(())
    }
}

/// A sampled object placement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// World position of the object frame's origin.
    pub position: Vector3<f64>,
    /// World-from-object rotation: yaw about Z after the optional flip.
    pub rotation: UnitQuaternion<f64>,
    pub yaw: f64,
    pub upside_down: bool,
    pub on_border: bool,
}

impl Placement {
    pub fn to_world(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.position
    }

    pub fn to_object(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.inverse_transform_vector(&(p - self.position))
    }
}

/// The flip used for upside-down placements: half a turn about the object's Y.
fn flip(upside_down: bool) -> UnitQuaternion<f64> {
    if upside_down {
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), PI)
    } else {
        UnitQuaternion::identity()
    }
}

/// Samples the object's pose on the table for a grasp of `part`.
/// `z_range` is the object's extent along its own Z (mesh min and max z).
pub fn sample_placement<R: Rng>(
    cfg: &SceneConfig,
    part: &GraspPart,
    z_range: [f64; 2],
    rng: &mut R,
) -> Placement {
    let upside_down = match part.upside_down {
        UpsideDown::Never => false,
        UpsideDown::Must => true,
        UpsideDown::May => rng.gen::<f64>() < cfg.upside_down_probability,
    };
    let (lo, hi) = cfg.placement_bounds();
    let y = uniform(rng, lo[1], hi[1]);
    let x = if part.table_border {
        cfg.near_edge_x() + cfg.border_inset
    } else {
        uniform(rng, lo[0], hi[0])
    };
    let f = flip(upside_down);
    let part_dir = f * Vector3::from(part.center);
    let yaw = match cfg.border_yaw_jitter_deg {
        Some(jitter) if part.table_border && part_dir.xy().norm() > 0.01 => {
            // Turn the part's centre towards -X (the user), then jitter.
            PI - part_dir.y.atan2(part_dir.x) + uniform(rng, -jitter, jitter).to_radians()
        }
        _ => uniform(rng, 0.0, 2.0 * PI),
    };
    let yaw = yaw.rem_euclid(2.0 * PI);
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * f;
    // Rest the lowest point of the object on the table top.
    let lowest = if upside_down { -z_range[1] } else { z_range[0] };
    let z = cfg.table_height - lowest;
    Placement {
        position: Vector3::new(x, y, z),
        rotation,
        yaw,
        upside_down,
        on_border: part.table_border,
    }
}

/// Uniform sample in [lo, hi] (lo when the range is empty).
pub fn uniform<R: Rng>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    if hi > lo {
        rng.gen_range(lo..=hi)
    } else {
        lo
    }
}
