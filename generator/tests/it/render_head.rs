//! The egocentric head camera end to end: planned with the built-in catalog,
//! rendered (Workbench, 32 px, 3 frames) into `Wrist_d435` and `Head_d435`
//! with the same labels, verified, and its pose looks at the object.

use crate::render_common::{grasp_gen, have_blender};
use generator::catalog::Catalog;
use grasp_schema::dataset::{
    head_sequence_dir, ManifestEntry, SequenceRecord, MANIFEST_FILE, SEQUENCE_FILE,
};
use nalgebra::{UnitQuaternion, Vector3};
use std::path::Path;

fn config(dir: &Path, head: bool) -> std::path::PathBuf {
    let text = format!(
        "[dataset]\nsequences_per_pair = 1\nconditions = [\"default\", \"seated\"]\n\
         objects = [\"025_mug\"]\nparts = [\"handle\", \"body\"]\n\n\
         [plan.camera]\nresolution = [32, 32]\n\n[plan.trajectory]\nfps = 1.0\n\n\
         [plan.conditions.seated]\nduration_s = 3.0\n\n\
         [plan.head_camera]\nenabled = {head}\n\n\
         [render]\nengine = \"workbench\"\nsamples = 1\n"
    );
    let path = dir.join(format!("head-{head}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

fn read_record(dir: &Path) -> SequenceRecord {
    serde_json::from_str(&std::fs::read_to_string(dir.join(SEQUENCE_FILE)).unwrap()).unwrap()
}

/// World centre of the object's bounding box, as the planner aims at it.
fn object_center(record: &SequenceRecord) -> Vector3<f64> {
    let catalog = Catalog::builtin().unwrap();
    let mesh = catalog
        .object(&record.plan.key.object)
        .unwrap()
        .mesh()
        .unwrap();
    let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
    for v in &mesh.vertices {
        lo = lo.inf(&Vector3::from(*v));
        hi = hi.sup(&Vector3::from(*v));
    }
    let pose = &record.plan.object.pose;
    let [w, x, y, z] = pose.rotation_wxyz;
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    q * ((lo + hi) / 2.0) + Vector3::from(pose.position)
}

#[test]
fn head_camera_renders_a_second_folder_with_the_same_labels() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), true);
    let out = dir.path().join("data");
    let (cfg_s, out_s) = (cfg.to_str().unwrap(), out.to_str().unwrap());
    grasp_gen().ok(["render", "--config", cfg_s, "--out", out_s, "--no-progress"]);
    let text = grasp_gen()
        .ok(["dataset", "verify", out_s, "--config", cfg_s, "--decode"])
        .stdout;
    assert!(
        text.contains("head camera: 4 sequences, 12 frames"),
        "{text}"
    );
    assert!(
        text.contains("render cost Head_d435: ") && text.contains("over 12 frames"),
        "{text}"
    );

    let manifest = std::fs::read_to_string(out.join(MANIFEST_FILE)).unwrap();
    let entries: Vec<ManifestEntry> = manifest
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(entries.len(), 4, "the manifest lists wrist folders only");
    for e in &entries {
        let wrist_dir = out.join(&e.path);
        let head_dir = out.join(head_sequence_dir(&e.path).unwrap());
        let (wrist, head) = (read_record(&wrist_dir), read_record(&head_dir));
        assert_eq!(wrist.plan, head.plan);
        assert_eq!(wrist.frame_files, head.frame_files);
        assert_eq!(wrist.plan.labels(), head.plan.labels());
        assert_eq!(wrist.frame_files.len(), 3);
        for f in &head.frame_files {
            assert_eq!(image::image_dimensions(head_dir.join(f)).unwrap(), (32, 32));
        }
        // The head view differs from the wrist view.
        let last = wrist.frame_files.last().unwrap();
        assert_ne!(
            image::open(wrist_dir.join(last)).unwrap().to_rgb8(),
            image::open(head_dir.join(last)).unwrap().to_rgb8()
        );
        // Static, and fixating the object within the 3-degree jitter cone.
        let center = object_center(&wrist);
        let first = wrist.plan.frames[0].head_camera.unwrap();
        for f in &wrist.plan.frames {
            let pose = f.head_camera.expect("every frame has a head pose");
            assert_eq!(pose, first);
            let [w, x, y, z] = pose.rotation_wxyz;
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            let forward = q * -Vector3::z();
            let angle = forward.angle(&(center - Vector3::from(pose.position)));
            assert!(
                angle.to_degrees() <= 3.0 + 1e-6,
                "{} deg",
                angle.to_degrees()
            );
        }
        // Seated users' eyes are lower.
        let eye_z = first.position[2];
        let seated = wrist.plan.key.condition == grasp_schema::Condition::Seated;
        assert!(if seated { eye_z < 1.3 } else { eye_z > 1.45 }, "{eye_z}");
        // Both cameras' render time is recorded.
        let cost = wrist.render_cost().expect("render cost");
        assert!(cost.camera_seconds["Wrist_d435"] > 0.0);
        assert!(cost.camera_seconds["Head_d435"] > 0.0);
    }

    // The stats read both cameras' cost.
    let stats: serde_json::Value =
        serde_json::from_str(&grasp_gen().ok(["dataset", "stats", out_s, "--json"]).stdout)
            .unwrap();
    for camera in ["Wrist_d435", "Head_d435"] {
        assert_eq!(stats["cameras"][camera]["frames"], 12, "{stats}");
        assert!(
            stats["cameras"][camera]["seconds_per_frame"]
                .as_f64()
                .unwrap()
                > 0.0
        );
    }

    // A head folder removed after the fact is reported, and --resume redoes it.
    let victim = head_sequence_dir(&entries[0].path).unwrap();
    std::fs::remove_dir_all(out.join(&victim)).unwrap();
    let bad = grasp_gen()
        .command(["dataset", "verify", out_s])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stdout).contains(&format!("{victim}: missing")));
    grasp_gen().ok([
        "render",
        "--config",
        cfg_s,
        "--out",
        out_s,
        "--resume",
        "--no-progress",
    ]);
    grasp_gen().ok(["dataset", "verify", out_s, "--config", cfg_s]);
}

#[test]
fn the_head_camera_changes_nothing_else_in_the_plan() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let plans = |head: bool| -> Vec<grasp_schema::SequencePlan> {
        let cfg = config(dir.path(), head);
        let out = dir.path().join(format!("plans-{head}.jsonl"));
        grasp_gen().ok([
            "plan",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        std::fs::read_to_string(&out)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    };
    let (off, on) = (plans(false), plans(true));
    assert_eq!(off.len(), 4);
    for (a, mut b) in off.into_iter().zip(on) {
        assert!(a.frames.iter().all(|f| f.head_camera.is_none()));
        assert!(b.frames.iter().all(|f| f.head_camera.is_some()));
        assert!(b.sampled.contains_key("head_eye"));
        let elbows = b.sampled["head_elbows"].as_array().unwrap();
        assert_eq!(elbows.len(), b.frames.len());
        for f in &mut b.frames {
            f.head_camera = None;
        }
        b.sampled.retain(|k, _| !k.starts_with("head_"));
        assert_eq!(a, b);
    }
}

#[test]
fn the_egocentric_config_turns_the_head_camera_on() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/egocentric.toml");
    let c = generator::config::GeneratorConfig::load(&path).unwrap();
    assert!(c.plan.head_camera.enabled);
    c.plan.validate().unwrap();
    let default = generator::config::GeneratorConfig::default();
    assert!(!default.plan.head_camera.enabled);
}
