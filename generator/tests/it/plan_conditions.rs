//! Behaviour of the condition presets, labels, determinism and the
//! validity rule, on a synthetic carton (mesh queries in Rust).

use crate::plan_support::*;
use generator::config::GeneratorConfig;
use generator::plan::trajectory::{Path, ViaPath};
use grasp_schema::{Class, Condition};
use nalgebra::Vector3;

fn plan(
    config: &GeneratorConfig,
    part: &str,
    index: u32,
    c: Condition,
) -> grasp_schema::SequencePlan {
    carton_planner(config, 1.0)
        .plan(&key(part, index, c))
        .unwrap()
}

#[test]
fn labels_follow_the_no_grasp_tail() {
    let c = GeneratorConfig::default();
    let p = plan(&c, "side", 0, Condition::Default);
    assert_eq!(p.frames.len(), 90);
    assert!((p.duration_s - 3.0).abs() < 1e-12);
    let labels = p.labels();
    assert!(labels[..75].iter().all(|l| *l == Class::Power));
    assert!(labels[75..].iter().all(|l| *l == Class::NoGrasp));
    let fast = plan(&c, "top", 0, Condition::Fast);
    assert_eq!(fast.frames.len(), 45);
    assert_eq!(
        fast.labels()
            .iter()
            .filter(|l| **l == Class::NoGrasp)
            .count(),
        15
    );
    assert_eq!(fast.labels()[0], Class::Pinch3);
}

#[test]
fn plans_are_pure_functions_of_key_seed_and_config() {
    let c = GeneratorConfig::default();
    for cond in Condition::ALL {
        let a = plan(&c, "side", 7, cond);
        let b = plan(&c, "side", 7, cond);
        assert_eq!(
            serde_json::to_string(&a).unwrap(),
            serde_json::to_string(&b).unwrap()
        );
        assert_sane(&a);
        assert_eq!(a.key.condition, cond);
    }
    // The batch size of the mesh queries does not change the result.
    let mut one = c.clone();
    one.plan.validity.batch_size = 1;
    for i in 0..10 {
        assert_eq!(
            plan(&c, "side", i, Condition::Default),
            plan(&one, "side", i, Condition::Default)
        );
    }
    // Another seed gives another plan.
    let mut other = c.clone();
    other.dataset.seed += 1;
    assert_ne!(
        plan(&c, "side", 0, Condition::Default).frames,
        plan(&other, "side", 0, Condition::Default).frames
    );
}

#[test]
fn default_starts_lie_in_the_configured_region() {
    let c = GeneratorConfig::default();
    let st = &c.plan.camera.start;
    for i in 0..40 {
        let p = plan(
            &c,
            if i % 2 == 0 { "side" } else { "top" },
            i,
            Condition::Default,
        );
        let start = Vector3::from(p.frames[0].camera.position);
        let target = Vector3::from(p.target);
        let d = (target - start).norm();
        assert!(
            d >= st.distance_m[0] && d <= st.distance_m[1],
            "distance {d}"
        );
        let h = start.z - c.plan.scene.table_height;
        assert!(h >= st.height_m[0] - 1e-12 && h <= st.height_m[1] + 1e-12);
        // The camera looks at the target at the start.
        let v = view_dir(p.frames[0].camera.rotation_wxyz);
        assert!((v - (target - start).normalize()).norm() < 1e-9);
        // Standoff: the camera stops short of the target, on the line, by
        // the sequence's standoff (the standoff lever's draw).
        let end = Vector3::from(p.frames.last().unwrap().camera.position);
        let standoff = p.sampled["standoff_m"].as_f64().unwrap();
        assert!(((target - end).norm() - standoff).abs() < 1e-9);
    }
}

#[test]
fn the_side_part_is_only_reached_from_its_side() {
    let c = GeneratorConfig::default();
    for i in 0..30 {
        let p = plan(&c, "side", i, Condition::Default);
        // The part sits on the object's -X face: every accepted start lies
        // on that side of the object (object frame x < -4 cm).
        let q = generator::plan::wrist::from_wxyz(p.object.pose.rotation_wxyz);
        let start = Vector3::from(p.frames[0].camera.position);
        let local = q.inverse() * (start - Vector3::from(p.object.pose.position));
        assert!(local.x < -0.04, "start {local:?} is not on the part's side");
    }
}

#[test]
fn a_part_buried_in_the_mesh_fails_with_object_part_and_reason() {
    let (mut spec, mesh, body) = box_object(1.0);
    spec.parts[0].center = [0.0, 0.0, 0.08]; // deep inside the body
    let geo = generator::plan::ObjectGeometry::new(
        spec,
        &mesh,
        Box::new(generator::plan::validity::BoxMesh(body)),
    )
    .unwrap();
    let mut c = GeneratorConfig::default();
    c.plan.trajectory.max_attempts = 50;
    let planner = generator::plan::Planner::from_geometries(&c, vec![geo]).unwrap();
    let err = planner
        .plan(&key("top", 0, Condition::Default))
        .unwrap_err();
    let msg = format!("{:#}", anyhow::Error::from(err));
    assert!(msg.contains("object test_carton, part top"), "{msg}");
    assert!(
        msg.contains("hits the object's mesh before the target box"),
        "{msg}"
    );
}

#[test]
fn tolerance_use_is_recorded() {
    // The top part sunk 3 mm under the lid: strict checks fail, the 5 mm
    // tolerance accepts and the plan says so.
    let (mut spec, mesh, body) = box_object(1.0);
    spec.parts[0].center = [0.0, 0.0, 0.16 - 0.003 - 0.005];
    let geo = |spec| {
        generator::plan::ObjectGeometry::new(
            spec,
            &mesh,
            Box::new(generator::plan::validity::BoxMesh(body)),
        )
        .unwrap()
    };
    let mut c = GeneratorConfig::default();
    c.plan.trajectory.max_attempts = 100;
    let planner = generator::plan::Planner::from_geometries(&c, vec![geo(spec.clone())]).unwrap();
    let p = planner.plan(&key("top", 0, Condition::Default)).unwrap();
    assert_eq!(p.sampled["mesh_tolerance_used"], true);
    let gap = p.sampled["mesh_contact_before_box_m"].as_f64().unwrap();
    assert!(gap > 0.0 && gap <= 0.005, "{gap}");
    c.plan.validity.mesh_tolerance_m = 0.0;
    let strict = generator::plan::Planner::from_geometries(&c, vec![geo(spec)]).unwrap();
    assert!(strict.plan(&key("top", 0, Condition::Default)).is_err());
}

#[test]
fn from_ground_starts_facing_the_floor_and_rises_smoothly() {
    let c = GeneratorConfig::default();
    for i in 0..10 {
        let p = plan(&c, "top", i, Condition::FromGround);
        assert_sane(&p);
        assert!((p.duration_s - 4.0).abs() < 1e-12);
        let v0 = view_dir(p.frames[0].camera.rotation_wxyz);
        assert!(v0.z < -0.999, "first frame looks at the floor: {v0:?}");
        let start = Vector3::from(p.frames[0].camera.position);
        assert!(
            start.x < c.plan.scene.near_edge_x(),
            "the hand hangs in front of the table"
        );
        // Frame-to-frame steps change smoothly (no velocity jump at the via-point).
        let pos: Vec<Vector3<f64>> = p
            .frames
            .iter()
            .map(|f| Vector3::from(f.camera.position))
            .collect();
        let steps: Vec<Vector3<f64>> = pos.windows(2).map(|w| w[1] - w[0]).collect();
        let max_step = steps.iter().map(|s| s.norm()).fold(0.0, f64::max);
        for w in steps.windows(2) {
            assert!(
                (w[1] - w[0]).norm() < 0.2 * max_step,
                "velocity jump in sequence {i}"
            );
        }
        // Orientation changes smoothly too.
        for w in p.frames.windows(2) {
            let (a, b) = (w[0].camera.rotation_wxyz, w[1].camera.rotation_wxyz);
            let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
            assert!(dot.abs() > (0.1f64).cos(), "orientation jump");
        }
    }
}

#[test]
fn via_point_velocity_is_continuous() {
    let via = ViaPath::new(
        Vector3::new(-0.6, -0.25, 0.75),
        Vector3::new(-0.4, 0.0, 1.1),
        Vector3::new(-0.05, 0.0, 0.95),
        0.42,
    );
    let p = Path::Via(via);
    // A jump would leave a gap that does not shrink with h; continuity makes
    // the gap shrink linearly (2 h |a|) and the acceleration gap likewise.
    let gap = |h: f64| (p.velocity(0.42 + h) - p.velocity(0.42 - h)).norm();
    let agap = |h: f64| (p.acceleration(0.42 + h) - p.acceleration(0.42 - h)).norm();
    let scale = p.velocity(0.42).norm();
    assert!(gap(1e-8) < 1e-6 * scale, "{}", gap(1e-8));
    assert!((gap(1e-4) / gap(1e-2) - 1e-2).abs() < 2e-3);
    assert!(agap(1e-6) / agap(1e-3) < 2e-3);
    assert!((p.position(0.42) - via.via).norm() < 1e-12);
    assert!(p.velocity(0.42).norm() > 0.0);
}

#[test]
fn seated_starts_lower_and_closer_and_curves() {
    let c = GeneratorConfig::default();
    let (mut seated_h, mut default_h, mut seated_d, mut default_d) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..20 {
        let s = plan(&c, "top", i, Condition::Seated);
        let d = plan(&c, "top", i, Condition::Default);
        assert!((s.duration_s - 1.5).abs() < 1e-12);
        let start = |p: &grasp_schema::SequencePlan| Vector3::from(p.frames[0].camera.position);
        seated_h += start(&s).z;
        default_h += start(&d).z;
        seated_d += (Vector3::from(s.target) - start(&s)).norm();
        default_d += (Vector3::from(d.target) - start(&d)).norm();
        // Curved: the path leaves the start-end chord by more than 1 cm.
        let (a, b) = (
            start(&s),
            Vector3::from(s.frames.last().unwrap().camera.position),
        );
        let dev = s
            .frames
            .iter()
            .map(|f| {
                let p = Vector3::from(f.camera.position) - a;
                let u = (b - a).normalize();
                (p - u * p.dot(&u)).norm()
            })
            .fold(0.0, f64::max);
        assert!(dev > 0.01, "seated path {i} is straight");
    }
    assert!(seated_h < default_h && seated_d < default_d);
}

#[test]
fn human_wrist_timing_starts_rotating_at_onset() {
    let mut c = GeneratorConfig::default();
    let authors = plan(&c, "side", 4, Condition::Default);
    c.plan.trajectory.wrist_timing = generator::plan::trajectory::WristTiming::Human;
    let human = plan(&c, "side", 4, Condition::Default);
    // Same path, same final orientation...
    assert_eq!(
        authors.frames[0].camera.position,
        human.frames[0].camera.position
    );
    let (qa, qh) = (
        authors.frames.last().unwrap().camera.rotation_wxyz,
        human.frames.last().unwrap().camera.rotation_wxyz,
    );
    let dot: f64 = qa.iter().zip(qh).map(|(x, y)| x * y).sum();
    assert!(dot.abs() > 1.0 - 1e-9);
    // ...but the human roll is already under way at frame 10 (the authors'
    // starts at frame 25 or later) whenever there is a roll to make.
    let ps = authors.sampled["ps_angle_deg"].as_f64().unwrap();
    if ps.abs() > 1.0 {
        assert_eq!(authors.frames[10].camera.rotation_wxyz, {
            let mut c0 = c.clone();
            c0.plan.trajectory.wrist_timing = generator::plan::trajectory::WristTiming::Authors;
            plan(&c0, "side", 4, Condition::Default).frames[10]
                .camera
                .rotation_wxyz
        });
        assert_ne!(
            authors.frames[10].camera.rotation_wxyz,
            human.frames[10].camera.rotation_wxyz
        );
    }
}

#[test]
fn full_roll_aligns_the_camera_x_with_the_box_x() {
    let mut c = GeneratorConfig::default();
    c.plan.trajectory.ps_fraction = [1.0, 1.0];
    c.plan.trajectory.fe_rate_per_frame = 0.0;
    let planner = carton_planner(&c, 1.0);
    let geo = planner.object("test_carton").unwrap();
    for part in ["side", "top"] {
        for i in 0..10 {
            let p = planner.plan(&key(part, i, Condition::Default)).unwrap();
            let last = p.frames.last().unwrap();
            let q = generator::plan::wrist::from_wxyz(last.camera.rotation_wxyz);
            let obj = generator::plan::wrist::from_wxyz(p.object.pose.rotation_wxyz);
            let box_x = obj * (geo.boxes[p.part_index].rotation * Vector3::x());
            let view = q * -Vector3::z();
            let proj = (box_x - view * view.dot(&box_x)).normalize();
            let right = q * Vector3::x();
            assert!(right.dot(&proj).abs() > 1.0 - 1e-9, "{part} {i}");
            // The shortest rule never rolls by more than 90 degrees.
            assert!(p.sampled["ps_angle_deg"].as_f64().unwrap().abs() <= 90.0);
        }
    }
}
