//! Numerical stability of the planner (issue item 8): degenerate starts, one
//! and 100 000 frames, vertical approaches, near-180-degree wrist rolls,
//! tiny and huge scenes, unit quaternions, the minimum-jerk velocity profile.

use crate::plan_support::*;
use generator::config::GeneratorConfig;
use generator::plan::conditions::straight_approach;
use generator::plan::trajectory::{min_jerk, Path};
use generator::plan::wrist::{self, look_at};
use grasp_schema::{Class, Condition};
use nalgebra::{UnitQuaternion, Vector3};

#[test]
fn start_equal_to_target_is_a_clear_error() {
    let t = Vector3::new(0.0, 0.0, 0.8);
    let err = straight_approach(&t, &t, 0.12).unwrap_err();
    assert!(
        err.to_string().contains("coincides with the target"),
        "{err}"
    );
    // The planner rejects such starts as candidates and names the reason
    // when none is left.
    let mut c = GeneratorConfig::default();
    let st = &mut c.plan.camera.start;
    st.plane_distance_m = [0.0, 0.0];
    st.lateral_m = [0.0, 0.0];
    st.height_m = [0.0, 0.0];
    st.distance_m = [0.0, 0.7];
    c.plan.trajectory.max_attempts = 20;
    c.plan.scene.placement_size = [0.0, 0.0];
    let err = carton_planner(&c, 1.0)
        .plan(&key("side", 0, Condition::Default))
        .unwrap_err();
    let msg = format!("{:#}", anyhow::Error::from(err));
    assert!(msg.contains("test_carton") && msg.contains("side"), "{msg}");
    assert!(
        msg.contains("no valid default approach in 20 attempts"),
        "{msg}"
    );
}

#[test]
fn a_single_frame_sits_at_the_start() {
    let mut c = GeneratorConfig::default();
    c.plan.trajectory.duration_s = 1.0 / 30.0;
    c.plan.trajectory.no_grasp_tail_s = 0.0;
    let plan = carton_planner(&c, 1.0)
        .plan(&key("top", 0, Condition::Default))
        .unwrap();
    assert_eq!(plan.frames.len(), 1);
    assert_sane(&plan);
    let start = plan.sampled["start"].as_array().unwrap();
    for (k, x) in start.iter().enumerate() {
        assert_eq!(plan.frames[0].camera.position[k], x.as_f64().unwrap());
    }
    assert_eq!(plan.frames[0].class, Class::Pinch3);
}

#[test]
fn one_hundred_thousand_frames_end_exactly_on_the_end_point() {
    let mut c = GeneratorConfig::default();
    c.plan.trajectory.fps = 100_000.0 / 3.0;
    let plan = carton_planner(&c, 1.0)
        .plan(&key("top", 3, Condition::Default))
        .unwrap();
    assert_eq!(plan.frames.len(), 100_000);
    assert_sane(&plan);
    let end: Vec<f64> = plan.sampled["end"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let last = plan.frames.last().unwrap().camera.position;
    for k in 0..3 {
        assert!(
            (last[k] - end[k]).abs() <= 1e-15 * end[k].abs().max(1.0),
            "axis {k}"
        );
    }
    // Progress along the line never goes backwards.
    let start = Vector3::from(plan.frames[0].camera.position);
    let dir = Vector3::from(last) - start;
    let mut prev = -1.0;
    for f in &plan.frames {
        let s = (Vector3::from(f.camera.position) - start).dot(&dir);
        assert!(s >= prev - 1e-15);
        prev = s;
    }
    // The last 0.5 s (16 667 frames) are no_grasp.
    let tail = plan
        .frames
        .iter()
        .filter(|f| f.class == Class::NoGrasp)
        .count();
    assert_eq!(tail, 16_667);
}

#[test]
fn target_straight_below_and_above_the_camera() {
    let up = Vector3::z();
    for dir in [-up, up, Vector3::new(1e-17, -1e-17, -1.0)] {
        let q = look_at(&dir, &up, &Vector3::x());
        assert!((q.quaternion().norm() - 1.0).abs() < 1e-12);
        assert!((wrist::view_direction(&q) - dir.normalize()).norm() < 1e-12);
    }
    // A plan whose start is exactly above the target (top part, no lateral
    // or horizontal offset).
    let mut c = GeneratorConfig::default();
    let st = &mut c.plan.camera.start;
    st.plane_distance_m = [0.0, 0.0];
    st.lateral_m = [0.0, 0.0];
    c.plan.validity.require_object_in_view = false;
    let plan = carton_planner(&c, 1.0)
        .plan(&key("top", 1, Condition::Default))
        .unwrap();
    assert_sane(&plan);
    let first = view_dir(plan.frames[0].camera.rotation_wxyz);
    assert!(first.z < -0.999_999, "looking straight down: {first:?}");
}

#[test]
fn near_half_turn_rolls_progress_smoothly() {
    let q0 = look_at(&Vector3::new(1.0, 0.2, -0.4), &Vector3::z(), &Vector3::x());
    for angle_deg in [179.0, 179.999, 180.0, -179.999] {
        let angle = f64::to_radians(angle_deg);
        let n = 200;
        let mut prev = q0;
        for i in 1..=n {
            let q = wrist::roll(&q0, angle * min_jerk(i as f64 / n as f64));
            assert!((q.quaternion().norm() - 1.0).abs() < 1e-12);
            // Consecutive frames differ by a small rotation: no flip.
            assert!(prev.angle_to(&q) < 0.03, "{angle_deg} deg, step {i}");
            // The view direction never changes under a roll.
            assert!((wrist::view_direction(&q) - wrist::view_direction(&q0)).norm() < 1e-12);
            prev = q;
        }
        assert!((prev.angle_to(&q0) - angle.abs()).abs() < 1e-9);
    }
    // Slerp between orientations a half turn apart stays defined.
    let b = q0 * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI);
    let mid = wrist::slerp(&q0, &b, 0.5);
    assert!((mid.angle_to(&q0) - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
}

#[test]
fn tiny_and_huge_scenes_plan_the_same_shape() {
    let reference = carton_planner(&scaled_config(1.0), 1.0)
        .plan(&key("side", 5, Condition::Default))
        .unwrap();
    for k in [1e-3, 1e3] {
        let plan = carton_planner(&scaled_config(k), k)
            .plan(&key("side", 5, Condition::Default))
            .unwrap();
        assert_sane(&plan);
        // Same random draws, same geometry up to scale.
        assert_eq!(plan.sampled["attempts"], reference.sampled["attempts"]);
        for (a, b) in plan.frames.iter().zip(&reference.frames) {
            for i in 0..3 {
                let scaled = b.camera.position[i] * k;
                assert!((a.camera.position[i] - scaled).abs() <= 1e-9 * k, "k {k}");
            }
            let (qa, qb) = (a.camera.rotation_wxyz, b.camera.rotation_wxyz);
            let dot: f64 = qa.iter().zip(qb).map(|(x, y)| x * y).sum();
            assert!(dot.abs() > 1.0 - 1e-9, "orientation differs at scale {k}");
        }
    }
}

#[test]
fn velocity_profile_is_bell_shaped_with_the_textbook_peak() {
    let (a, b) = (
        Vector3::new(-0.45, 0.12, 1.05),
        Vector3::new(0.05, -0.03, 0.8),
    );
    let path = Path::Straight { start: a, end: b };
    let d = (b - a).norm();
    let duration = 3.0;
    let speed = |tau: f64| path.velocity(tau).norm() / duration;
    assert_eq!(speed(0.0), 0.0);
    assert_eq!(speed(1.0), 0.0);
    assert!(path.acceleration(0.0).norm() == 0.0);
    assert!(path.acceleration(1.0).norm() < 1e-12 * d);
    let peak = 1.875 * d / duration;
    assert!((speed(0.5) - peak).abs() <= 1e-9 * peak);
    // The peak is the maximum and the profile is symmetric.
    for k in 0..=1000 {
        let t = k as f64 / 1000.0;
        assert!(speed(t) <= peak * (1.0 + 1e-12));
        assert!((speed(t) - speed(1.0 - t)).abs() < 1e-12);
    }
    // Frame positions come from the closed form: the plan's frames match
    // x0 + (xf - x0) s(tau) exactly.
    let plan = carton_planner(&GeneratorConfig::default(), 1.0)
        .plan(&key("top", 2, Condition::Default))
        .unwrap();
    let n = plan.frames.len();
    let x0 = Vector3::from(plan.frames[0].camera.position);
    let xf = Vector3::from(plan.frames[n - 1].camera.position);
    for (i, f) in plan.frames.iter().enumerate() {
        let expect = x0 + (xf - x0) * min_jerk(i as f64 / (n - 1) as f64);
        assert!((Vector3::from(f.camera.position) - expect).norm() < 1e-15);
    }
}
