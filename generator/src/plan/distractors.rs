//! Distractors: primitives (boxes, cylinders, spheres) standing on the table
//! besides the target object (`[randomize.distractors]`).
//!
//! They are drawn after the reach is planned, from the sequence's own
//! `distractors` sub-stream, so they never change the path. A draw is kept
//! only when it
//! - stands on the table top, clear of the target object's bounding sphere
//!   (footprint circles `clearance_m` apart) and of the other distractors;
//! - stays off the reach: the validity machinery's box test ([`Obb`]) of
//!   the box grown by `clearance_m` against every chord of the camera path
//!   and every line of sight from a path point to the target.
//!
//! A distractor that fails `attempts` draws is left out (the count of
//! rejected draws is recorded). Distractors hold no part, and the renderer
//! gives them no object index, so no label or mask ever covers them.

use super::scene::SceneConfig;
use super::validity::Obb;
use crate::look::lever_rng;
use crate::randomize::DistractorLever;
use grasp_schema::plan::{Distractor, Pose};
use nalgebra::{UnitQuaternion, Vector3};
use rand::Rng;

/// What the distractors must keep clear of, in the world frame.
pub struct Keepout<'a> {
    /// Bounding sphere of the placed target object.
    pub object_center: Vector3<f64>,
    pub object_radius: f64,
    /// The camera path as a polyline (start ... end).
    pub path: &'a [Vector3<f64>],
    /// The point the reach aims at.
    pub target: Vector3<f64>,
}

impl Keepout<'_> {
    /// Whether the box crosses the reach or a line of sight to the target.
    fn blocks(&self, grown: &Obb) -> bool {
        let chords = self.path.windows(2).map(|w| (w[0], w[1]));
        let end = self.path.last().map(|p| (*p, self.target));
        let sights = self.path.iter().map(|p| (*p, self.target));
        chords
            .chain(end)
            .chain(sights)
            .any(|(a, b)| grown.segment_entry(&a, &b).is_some())
    }
}

/// One drawn distractor with its footprint radius.
struct Draw {
    distractor: Distractor,
    footprint: f64,
    center: Vector3<f64>,
    yaw: UnitQuaternion<f64>,
    half: Vector3<f64>,
}

/// The distractors of one sequence and the number of rejected draws.
pub fn sample(
    lever: &DistractorLever,
    scene: &SceneConfig,
    keepout: &Keepout<'_>,
    stream: u64,
) -> (Vec<Distractor>, u32) {
    let mut rng = lever_rng(stream, "distractors");
    let count = rng.gen_range(lever.count[0]..=lever.count[1].max(lever.count[0]));
    let mut kept: Vec<Draw> = Vec::new();
    let mut rejected = 0;
    for _ in 0..count {
        for _ in 0..lever.attempts {
            let d = draw(lever, scene, &mut rng);
            if fits(lever, keepout, &kept, &d) {
                kept.push(d);
                break;
            }
            rejected += 1;
        }
    }
    (kept.into_iter().map(|d| d.distractor).collect(), rejected)
}

fn draw(lever: &DistractorLever, scene: &SceneConfig, rng: &mut impl Rng) -> Draw {
    let shape = lever.shapes[rng.gen_range(0..lever.shapes.len().max(1))].clone();
    let mut size = [0.0; 3];
    for s in &mut size {
        *s = uniform_rng(rng, lever.size_m);
    }
    match shape.as_str() {
        "sphere" => size = [size[0]; 3],
        "cylinder" => size[1] = size[0],
        _ => {}
    }
    let footprint = if shape == "box" {
        (size[0] * size[0] + size[1] * size[1]).sqrt() / 2.0
    } else {
        size[0] / 2.0
    };
    let yaw_angle = uniform_rng(rng, [0.0, std::f64::consts::TAU]);
    let [cx, cy] = scene.table_center;
    let [sx, sy] = scene.table_size;
    let margin = footprint + 0.01;
    let x = uniform_rng(rng, [cx - sx / 2.0 + margin, cx + sx / 2.0 - margin]);
    let y = uniform_rng(rng, [cy - sy / 2.0 + margin, cy + sy / 2.0 - margin]);
    let center = Vector3::new(x, y, scene.table_height + size[2] / 2.0);
    let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_angle);
    let hue = uniform_rng(rng, [0.0, 1.0]);
    let sat = uniform_rng(rng, [0.05, 0.8]);
    let val = uniform_rng(rng, [0.15, 0.9]);
    let roughness = uniform_rng(rng, [0.3, 0.9]);
    Draw {
        distractor: Distractor {
            shape,
            size,
            pose: Pose {
                position: center.into(),
                rotation_wxyz: [yaw.w, yaw.i, yaw.j, yaw.k],
            },
            color: crate::appearance::hsv_to_linear_rgb(hue, sat, val),
            roughness,
        },
        footprint,
        center,
        yaw,
        half: Vector3::from(size) / 2.0,
    }
}

fn uniform_rng(rng: &mut impl Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        rng.gen_range(lo..hi)
    } else {
        lo
    }
}

/// Clear of the object, the other distractors and the reach.
fn fits(lever: &DistractorLever, k: &Keepout<'_>, kept: &[Draw], d: &Draw) -> bool {
    let c = lever.clearance_m;
    let flat = |v: &Vector3<f64>| v.xy();
    if (flat(&d.center) - flat(&k.object_center)).norm() < d.footprint + k.object_radius + c {
        return false;
    }
    if kept
        .iter()
        .any(|o| (flat(&d.center) - flat(&o.center)).norm() < d.footprint + o.footprint + c)
    {
        return false;
    }
    let grown = Obb {
        center: d.center,
        rotation: d.yaw,
        half: d.half.add_scalar(c),
    };
    !k.blocks(&grown)
}

/// The validity check of a finished plan's distractors (tests, verify):
/// the first distractor that crosses the reach or the object, if any.
pub fn first_blocking(
    distractors: &[Distractor],
    keepout: &Keepout<'_>,
    clearance_m: f64,
) -> Option<usize> {
    distractors.iter().position(|d| {
        let q = d.pose.rotation_wxyz;
        let rotation =
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
        let center = Vector3::from(d.pose.position);
        let half = Vector3::from(d.size) / 2.0;
        let footprint = if d.shape == "box" {
            half.xy().norm()
        } else {
            half.x
        };
        let apart = (center.xy() - keepout.object_center.xy()).norm();
        apart < footprint + keepout.object_radius + clearance_m
            || keepout.blocks(&Obb {
                center,
                rotation,
                half: half.add_scalar(clearance_m),
            })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::randomize::RandomizeConfig;

    #[test]
    fn distractors_keep_clear_and_are_deterministic() {
        let lever = DistractorLever {
            count: [3, 3],
            ..RandomizeConfig::default().distractors
        };
        let scene = SceneConfig::default();
        let path = [Vector3::new(-0.6, 0.0, 1.1), Vector3::new(-0.2, 0.0, 0.85)];
        let k = Keepout {
            object_center: Vector3::new(-0.1, 0.0, 0.8),
            object_radius: 0.06,
            path: &path,
            target: Vector3::new(-0.12, 0.0, 0.8),
        };
        let mut total = 0;
        for s in 0..200 {
            let (a, _) = sample(&lever, &scene, &k, s);
            assert_eq!(a, sample(&lever, &scene, &k, s).0);
            assert_eq!(first_blocking(&a, &k, lever.clearance_m), None);
            for d in &a {
                assert!((d.pose.position[2] - 0.75 - d.size[2] / 2.0).abs() < 1e-12);
            }
            total += a.len();
        }
        assert!(total > 400, "{total} distractors kept of 600");
    }

    #[test]
    fn a_box_on_the_path_is_caught() {
        let path = [Vector3::new(-0.6, 0.0, 0.8), Vector3::new(-0.2, 0.0, 0.8)];
        let k = Keepout {
            object_center: Vector3::new(0.2, 0.3, 0.8),
            object_radius: 0.05,
            path: &path,
            target: Vector3::new(-0.1, 0.0, 0.8),
        };
        let d = Distractor {
            shape: "box".into(),
            size: [0.05, 0.05, 0.1],
            pose: Pose {
                position: [-0.4, 0.0, 0.8],
                rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
            },
            color: [0.5; 3],
            roughness: 0.5,
        };
        assert_eq!(first_blocking(std::slice::from_ref(&d), &k, 0.0), Some(0));
        let aside = Distractor {
            pose: Pose {
                position: [-0.4, 0.3, 0.8],
                ..d.pose
            },
            ..d
        };
        assert_eq!(first_blocking(&[aside], &k, 0.02), None);
    }
}
