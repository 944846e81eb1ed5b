//! Hand-made sequences for the rendering tests: a few plans of a camera
//! approaching simple meshes on the table, tiny images, Workbench or Cycles
//! at one sample.

#![allow(dead_code)]

use generator::appearance::{sample, AppearanceConfig};
use generator::render::parts::PartBox;
use generator::render::source::{Mesh, StaticSource};
use generator::render::{Engine, RenderConfig, RenderOptions, SceneGeometry, Shard};
use grasp_schema::plan::{CameraIntrinsics, FramePlan, ObjectPlacement, Pose};
use grasp_schema::taxonomy::{GraspType, Preshape};
use grasp_schema::{Class, Condition, SequenceKey, SequencePlan};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

pub fn exe() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_grasp-gen"))
}

/// `grasp-gen` as a user runs it.
pub fn grasp_gen() -> grasp_test_support::Program {
    grasp_test_support::Program::new(exe())
}

/// Whether the Python environment with bpy exists. Without it the calling
/// test is reported as skipped, or fails under `GRASP_REQUIRE_BLENDER=1`
/// (`scripts/test.sh`): see `grasp_test_support::prerequisite`.
pub fn have_blender() -> bool {
    let missing = generator::python::site_packages(&generator::python::venv_dir())
        .err()
        .map(|_| {
            format!(
                "there is no Python venv with bpy ({})",
                generator::python::setup_hint()
            )
        });
    let test = std::thread::current()
        .name()
        .unwrap_or("a Blender test")
        .to_string();
    grasp_test_support::prerequisite::check(
        &test,
        grasp_test_support::prerequisite::REQUIRE_BLENDER_ENV,
        missing,
    )
}

/// A box mesh `size` metres, resting on z = 0.
pub fn box_mesh(size: [f64; 3]) -> Mesh {
    let [x, y, z] = size.map(|s| s / 2.0);
    let vertices = vec![
        [-x, -y, 0.0],
        [x, -y, 0.0],
        [x, y, 0.0],
        [-x, y, 0.0],
        [-x, -y, 2.0 * z],
        [x, -y, 2.0 * z],
        [x, y, 2.0 * z],
        [-x, y, 2.0 * z],
    ];
    let quads = [
        [0, 3, 2, 1],
        [4, 5, 6, 7],
        [0, 1, 5, 4],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 0, 4, 7],
    ];
    let faces = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Mesh { vertices, faces }
}

/// Quaternion (w, x, y, z) of a camera at `from` looking at `to`, +Y up-ish.
pub fn look_at(from: [f64; 3], to: [f64; 3]) -> [f64; 4] {
    use nalgebra::{Rotation3, UnitQuaternion, Vector3};
    let forward = (Vector3::from(to) - Vector3::from(from)).normalize();
    let z = -forward; // the camera looks along its -Z
    let x = Vector3::z().cross(&z).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_basis_unchecked(&[x, y, z]);
    let q = UnitQuaternion::from_rotation_matrix(&r);
    [q.w, q.i, q.j, q.k]
}

pub fn plan(
    object: &str,
    part: &str,
    index: u32,
    condition: Condition,
    frames: usize,
    px: u32,
) -> SequencePlan {
    let key = SequenceKey {
        object: object.into(),
        part: part.into(),
        index,
        condition,
    };
    let seed = key.stream_seed(42);
    let target = [0.0, 0.0, 0.8];
    let frames = (0..frames)
        .map(|i| {
            let t = i as f64 / (frames.max(2) - 1) as f64;
            let from = [0.05 * index as f64, -0.7 + 0.45 * t, 1.15 - 0.25 * t];
            FramePlan {
                index: i as u32,
                time_s: t,
                camera: Pose {
                    position: from,
                    rotation_wxyz: look_at(from, target),
                },
                class: if t < 0.3 {
                    Class::NoGrasp
                } else {
                    Class::Power
                },
                head_camera: None,
            }
        })
        .collect::<Vec<_>>();
    let f = px as f64 / (2.0 * (35f64.to_radians()).tan());
    SequencePlan {
        schema_version: grasp_schema::plan::PLAN_SCHEMA_VERSION,
        dataset_seed: 42,
        key,
        stream_seed: seed,
        category: "box".into(),
        grasp_type: GraspType::LargeDiameter,
        preshape: Preshape::Power,
        part_index: 0,
        fps: 10.0,
        duration_s: 1.0,
        intrinsics: CameraIntrinsics {
            width: px,
            height: px,
            fx: f,
            fy: f,
            cx: px as f64 / 2.0,
            cy: px as f64 / 2.0,
            fov_x_deg: 70.0,
            fov_y_deg: 70.0,
            clip_near: 0.01,
            clip_far: 20.0,
        },
        object: ObjectPlacement {
            pose: Pose {
                position: [0.0, 0.0, 0.75],
                rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
            },
            yaw_deg: 0.0,
            upside_down: false,
            on_table_border: false,
            scale: 1.0,
            proportions: [1.0; 3],
        },
        target,
        other_end: target,
        frames,
        sampled: BTreeMap::new(),
        appearance: Some(sample(&AppearanceConfig::default(), condition, seed)),
        distractors: Vec::new(),
    }
}

/// `n` sequences over two objects, `frames` frames each.
pub fn source(n: u32, frames: usize, px: u32) -> StaticSource {
    let plans = (0..n)
        .map(|i| {
            let (object, cond) = if i % 2 == 0 {
                ("a_box", Condition::Default)
            } else {
                ("b_box", Condition::Background)
            };
            plan(object, "body", i, cond, frames, px)
        })
        .collect();
    let meshes = BTreeMap::from([
        ("a_box".to_string(), box_mesh([0.08, 0.08, 0.15])),
        ("b_box".to_string(), box_mesh([0.15, 0.06, 0.05])),
    ]);
    let parts = BTreeMap::from([
        ("a_box".to_string(), box_parts([0.08, 0.08, 0.15])),
        ("b_box".to_string(), box_parts([0.15, 0.06, 0.05])),
    ]);
    StaticSource {
        plans,
        meshes,
        parts,
        scene: SceneGeometry::default(),
    }
}

/// Two parts of a [`box_mesh`]: a 1 cm slab on its top face, then a box
/// around its sides below that (catalog order: top, sides).
pub fn box_parts(size: [f64; 3]) -> Vec<PartBox> {
    let [x, y, z] = size;
    vec![
        PartBox {
            name: "top".into(),
            center: [0.0, 0.0, z],
            rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
            size: [x, y, 0.01],
        },
        PartBox {
            name: "sides".into(),
            center: [0.0, 0.0, (z - 0.005) / 2.0],
            rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
            size: [x + 0.01, y + 0.01, z - 0.005],
        },
    ]
}

pub fn workbench() -> RenderConfig {
    RenderConfig {
        engine: Engine::Workbench,
        samples: 1,
        ..Default::default()
    }
}

pub fn options(out: &Path, workers: usize) -> RenderOptions {
    RenderOptions {
        out: out.to_path_buf(),
        workers,
        shard: Shard::ALL,
        resume: false,
        worker_exe: exe(),
        progress: false,
        stop: Arc::new(AtomicBool::new(false)),
        worker_env: Vec::new(),
        break_lock: false,
    }
}

/// Every file under `root` except the work folder, with its bytes; in
/// `sequence.json` files the wall-clock `render.cost` is dropped (it differs
/// between runs by nature; everything else must not).
pub fn tree(root: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.file_name().unwrap().to_string_lossy().starts_with('.') {
                continue;
            }
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                let mut bytes = std::fs::read(&p).unwrap();
                if rel.ends_with(grasp_schema::dataset::SEQUENCE_FILE) {
                    bytes = without_cost(&bytes);
                }
                out.insert(rel, bytes);
            }
        }
    }
    out
}

/// A `sequence.json` without its `render.cost`, which must be present.
fn without_cost(bytes: &[u8]) -> Vec<u8> {
    let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
    let render = v["render"].as_object_mut().unwrap();
    let cost = render.remove(grasp_schema::dataset::RENDER_COST_KEY);
    assert!(cost.is_some(), "sequence.json without render.cost");
    serde_json::to_vec_pretty(&v).unwrap()
}

/// Every `sequence.json` under `root`, by path relative to it.
pub fn records(root: &Path) -> Vec<(PathBuf, grasp_schema::dataset::SequenceRecord)> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() && !p.file_name().unwrap().to_string_lossy().starts_with('.') {
                stack.push(p);
            } else if p
                .file_name()
                .is_some_and(|n| n == grasp_schema::dataset::SEQUENCE_FILE)
            {
                let r = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
                out.push((p.strip_prefix(root).unwrap().to_path_buf(), r));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}
