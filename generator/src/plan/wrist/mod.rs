//! Camera orientation: look-at, pronation-supination (roll about the
//! approach axis) and flexion-extension (pitch about the camera's X axis),
//! all as unit quaternions.
//!
//! Camera frame (Blender convention): the camera looks along its local -Z,
//! +Y is up in the image and +X to the right. Following the authors' script,
//! pronation-supination turns the camera's +X axis onto the grasp box's local
//! X axis (the palm normal ends parallel to that face normal), and
//! flexion-extension turns the view about the camera's +X axis towards the
//! box's other end.

mod angles;
mod schedule;

pub use angles::{look_toward, WristAngles};
pub use schedule::WristSchedule;

use nalgebra::{Matrix3, Rotation3, Unit, UnitQuaternion, Vector3};

/// Below this |forward x up| the up hint is treated as parallel to the view.
const PARALLEL_EPS: f64 = 1e-9;

/// Orientation (world from camera) of a camera at the origin looking along
/// `forward`, with the image's up as close as possible to `up`. When
/// `forward` is parallel to `up` (a vertical approach), `fallback_up` is used
/// instead, so the result is always a proper unit quaternion.
pub fn look_at(
    forward: &Vector3<f64>,
    up: &Vector3<f64>,
    fallback_up: &Vector3<f64>,
) -> UnitQuaternion<f64> {
    let f = forward.normalize();
    let mut right = f.cross(up);
    if right.norm() < PARALLEL_EPS * up.norm().max(1.0) {
        right = f.cross(fallback_up);
    }
    if right.norm() < PARALLEL_EPS {
        // Both hints parallel to the view: any perpendicular axis will do.
        right = f.cross(&least_aligned_axis(&f));
    }
    let right = right.normalize();
    let image_up = right.cross(&f);
    let m = Matrix3::from_columns(&[right, image_up, -f]);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

fn least_aligned_axis(v: &Vector3<f64>) -> Vector3<f64> {
    let a = v.abs();
    if a.x <= a.y && a.x <= a.z {
        Vector3::x()
    } else if a.y <= a.z {
        Vector3::y()
    } else {
        Vector3::z()
    }
}

/// The camera's view direction (world) for an orientation.
pub fn view_direction(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    q * -Vector3::z()
}

/// The camera's right axis (world).
pub fn right_axis(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    q * Vector3::x()
}

/// Signed angle (radians, right-hand rule about `axis`) that turns `from`
/// onto the projection of `to` on the plane normal to `axis`. `None` when
/// `to` is (nearly) parallel to the axis, where no rotation is defined.
pub fn signed_angle_about(
    axis: &Vector3<f64>,
    from: &Vector3<f64>,
    to: &Vector3<f64>,
) -> Option<f64> {
    let a = axis.normalize();
    let p = to - a * a.dot(to);
    let f = from - a * a.dot(from);
    if p.norm() < 1e-9 * to.norm().max(1e-300) || f.norm() < 1e-12 {
        return None;
    }
    Some(f.cross(&p).dot(&a).atan2(f.dot(&p)))
}

/// How the pronation-supination angle is chosen from the box's X axis (an
/// axis, so both signs align the palm with a face).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RollRule {
    /// The smaller of the two rolls, in [-90, 90) degrees.
    Shortest,
    /// The roll of positive sign (supination of a right hand), in [0, 180).
    Supination,
}

/// Wraps a roll angle (radians) according to the rule.
pub fn wrap_roll(angle: f64, rule: RollRule) -> f64 {
    use std::f64::consts::PI;
    match rule {
        RollRule::Shortest => (angle + PI / 2.0).rem_euclid(PI) - PI / 2.0,
        RollRule::Supination => angle.rem_euclid(PI),
    }
}

/// Applies a roll about the camera's own view axis (-Z) by `angle` radians:
/// positive is a right-hand rotation about the view direction (supination of
/// a right hand).
pub fn roll(q: &UnitQuaternion<f64>, angle: f64) -> UnitQuaternion<f64> {
    q * UnitQuaternion::from_axis_angle(&-Vector3::z_axis(), angle)
}

/// Applies a pitch about the camera's own +X axis by `angle` radians.
pub fn pitch(q: &UnitQuaternion<f64>, angle: f64) -> UnitQuaternion<f64> {
    q * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), angle)
}

/// Spherical interpolation along the shorter arc; defined for every pair of
/// unit quaternions, including opposite rotations (where it turns about an
/// axis perpendicular to the view).
pub fn slerp(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, t: f64) -> UnitQuaternion<f64> {
    if let Some(q) = a.try_slerp(b, t, 1e-12) {
        return q;
    }
    // Exactly 180 degrees apart: the arc is ambiguous; pick a fixed axis.
    let rel = a.inverse() * b;
    let axis = rel
        .axis()
        .unwrap_or_else(|| Unit::new_normalize(least_aligned_axis(&Vector3::z())));
    a * UnitQuaternion::from_axis_angle(&axis, rel.angle() * t)
}

/// wxyz array of a quaternion, renormalised so stored poses are unit to
/// machine precision.
pub fn to_wxyz(q: &UnitQuaternion<f64>) -> [f64; 4] {
    let c = q.quaternion().coords.normalize();
    // nalgebra stores (x, y, z, w).
    [c[3], c[0], c[1], c[2]]
}

/// Quaternion from a wxyz array (normalised).
pub fn from_wxyz(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn look_at_points_the_camera_and_keeps_the_image_upright() {
        let f = Vector3::new(1.0, 0.2, -0.5);
        let q = look_at(&f, &Vector3::z(), &Vector3::x());
        assert!((view_direction(&q) - f.normalize()).norm() < 1e-12);
        let up = q * Vector3::y();
        assert!(up.z > 0.0);
        assert!(
            right_axis(&q).z.abs() < 1e-12,
            "no roll: the right axis is level"
        );
    }

    #[test]
    fn look_at_is_defined_straight_down_and_up() {
        for f in [-Vector3::z(), Vector3::z(), Vector3::new(1e-14, 0.0, -1.0)] {
            let q = look_at(&f, &Vector3::z(), &Vector3::x());
            assert!((q.quaternion().norm() - 1.0).abs() < 1e-12);
            assert!((view_direction(&q) - f.normalize()).norm() < 1e-9);
            assert!((q * Vector3::y()).x > 0.99, "image up is the fallback");
        }
    }

    #[test]
    fn roll_rules_wrap_into_their_ranges() {
        for k in -720..=720 {
            let a = (k as f64).to_radians();
            let s = wrap_roll(a, RollRule::Shortest);
            assert!((-PI / 2.0..PI / 2.0).contains(&s));
            let p = wrap_roll(a, RollRule::Supination);
            assert!((0.0..PI).contains(&p));
            // Both still align the axis: they differ from a by a multiple of pi.
            for w in [s, p] {
                let r = (a - w) / PI;
                assert!((r - r.round()).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn signed_angle_turns_from_onto_to() {
        let axis = Vector3::new(0.3, -0.2, 1.0);
        let from = Vector3::new(1.0, 0.0, 0.0);
        let to = Vector3::new(-0.2, 1.0, 0.4);
        let a = signed_angle_about(&axis, &from, &to).unwrap();
        let r = UnitQuaternion::from_axis_angle(&Unit::new_normalize(axis), a);
        let n = axis.normalize();
        let proj = |v: Vector3<f64>| (v - n * n.dot(&v)).normalize();
        assert!((proj(r * from) - proj(to)).norm() < 1e-12);
        assert!(signed_angle_about(&axis, &from, &(axis * 2.0)).is_none());
    }

    #[test]
    fn slerp_handles_opposite_and_equal_rotations() {
        let a = UnitQuaternion::identity();
        let b = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), PI);
        for t in [0.0, 0.25, 0.5, 1.0] {
            let q = slerp(&a, &b, t);
            assert!(q.coords.iter().all(|x| x.is_finite()));
            assert!((q.angle() - PI * t).abs() < 1e-9);
        }
        let q = slerp(&a, &a, 0.3);
        assert!(q.angle() < 1e-12);
    }

    #[test]
    fn wxyz_round_trip() {
        let q = UnitQuaternion::from_euler_angles(0.3, -1.2, 2.9);
        let back = from_wxyz(to_wxyz(&q));
        assert!(q.angle_to(&back) < 1e-12);
    }
}
