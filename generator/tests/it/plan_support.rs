//! Shared helpers of the planner tests: a synthetic box object whose mesh
//! queries run in Rust (no Python), and scaled configs.
#![allow(dead_code)]

use generator::catalog::{ObjectSpec, TriMesh};
use generator::config::GeneratorConfig;
use generator::plan::validity::{BoxMesh, Obb};
use generator::plan::{ObjectGeometry, Planner};
use grasp_schema::{Condition, GraspType, SequenceKey, SequencePlan};
use nalgebra::{UnitQuaternion, Vector3};

/// A standing box (k * 8 x 8 x 16 cm) with a part on top (tripod) and one
/// on its -X face (large diameter), like a small carton.
pub fn box_object(k: f64) -> (ObjectSpec, TriMesh, Obb) {
    let size = [0.08 * k, 0.08 * k, 0.16 * k];
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let part =
        |name: &str, g: GraspType, center: [f64; 3], rotation_wxyz: [f64; 4], size: [f64; 3]| {
            serde_json::json!({
                "name": name,
                "grasp_type": g,
                "center": center.map(|x| x * k),
                "rotation_wxyz": rotation_wxyz,
                "size": size.map(|x| x * k),
            })
        };
    // Built through serde: the catalog's ObjectSpec has private cache fields.
    let spec: ObjectSpec = serde_json::from_value(serde_json::json!({
        "id": "test_carton",
        "name": "Carton",
        "category": "carton",
        "size": size,
        // (The mesh below is used; a procedural spec lets every lever act.)
        "mesh": {"procedural": {"kind": "block", "size": size}},
        "parts": [
            part("top", GraspType::Tripod, [0.0, 0.0, 0.16], [1.0, 0.0, 0.0, 0.0], [0.03, 0.02, 0.01]),
            // Local Z along object X: the ends lie 5 mm outside and inside the -X face.
            part("side", GraspType::LargeDiameter, [-0.04, 0.0, 0.08], [s, 0.0, s, 0.0], [0.1, 0.06, 0.01]),
        ],
    }))
    .expect("a valid object spec");
    let vertices = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 {
                    -size[0] / 2.0
                } else {
                    size[0] / 2.0
                },
                if i & 2 == 0 {
                    -size[1] / 2.0
                } else {
                    size[1] / 2.0
                },
                if i & 4 == 0 { 0.0 } else { size[2] },
            ]
        })
        .collect();
    let body = Obb {
        center: Vector3::new(0.0, 0.0, size[2] / 2.0),
        rotation: UnitQuaternion::identity(),
        half: Vector3::from(size) / 2.0,
    };
    (
        spec,
        TriMesh {
            vertices,
            faces: vec![],
        },
        body,
    )
}

/// A planner over the synthetic carton.
pub fn carton_planner(config: &GeneratorConfig, k: f64) -> Planner {
    let (spec, mesh, body) = box_object(k);
    let geo = ObjectGeometry::new(spec, &mesh, Box::new(BoxMesh(body))).unwrap();
    Planner::from_geometries(config, vec![geo]).unwrap()
}

pub fn key(part: &str, index: u32, condition: Condition) -> SequenceKey {
    SequenceKey {
        object: "test_carton".to_string(),
        part: part.to_string(),
        index,
        condition,
    }
}

/// Every length of the default config times k.
pub fn scaled_config(k: f64) -> GeneratorConfig {
    let mut c = GeneratorConfig::default();
    let s = &mut c.plan.scene;
    s.room_size = s.room_size.map(|x| x * k);
    s.table_center = s.table_center.map(|x| x * k);
    s.table_size = s.table_size.map(|x| x * k);
    s.table_height *= k;
    s.table_thickness *= k;
    s.placement_center = s.placement_center.map(|x| x * k);
    s.placement_size = s.placement_size.map(|x| x * k);
    s.border_inset *= k;
    let cam = &mut c.plan.camera;
    cam.clip_m = cam.clip_m.map(|x| x * k);
    let st = &mut cam.start;
    for r in [
        &mut st.plane_distance_m,
        &mut st.lateral_m,
        &mut st.height_m,
        &mut st.distance_m,
    ] {
        *r = r.map(|x| x * k);
    }
    c.plan.trajectory.standoff_m *= k;
    c.plan.validity.mesh_tolerance_m *= k;
    let g = &mut c.plan.conditions.from_ground;
    for r in [
        &mut g.hang_behind_edge_m,
        &mut g.hang_lateral_m,
        &mut g.hang_height_m,
    ] {
        *r = r.map(|x| x * k);
    }
    c.plan.conditions.seated.lift_m = c.plan.conditions.seated.lift_m.map(|x| x * k);
    c
}

/// Asserts the invariants every plan must satisfy.
pub fn assert_sane(plan: &SequencePlan) {
    assert!(!plan.frames.is_empty());
    for f in &plan.frames {
        let q = f.camera.rotation_wxyz;
        let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(
            (n - 1.0).abs() < 1e-12,
            "frame {} quaternion norm {n}",
            f.index
        );
        assert!(f.camera.position.iter().all(|x| x.is_finite()));
    }
    let q = plan.object.pose.rotation_wxyz;
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!((n - 1.0).abs() < 1e-12);
}

/// View direction (world) of a stored camera pose.
pub fn view_dir(q: [f64; 4]) -> Vector3<f64> {
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
    q * -Vector3::z()
}
