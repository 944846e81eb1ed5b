//! The `unseen_look` condition and training's randomisation levers at the
//! planning level, on the synthetic carton (mesh queries in Rust): unseen
//! values never occur in training sets, validation refuses configs where
//! they could, every drawn value is in the plan and reproduces from the
//! seed, levers are independent, and distractors keep clear of the target
//! and the reach.

use crate::plan_support::*;
use generator::config::GeneratorConfig;
use generator::plan::distractors::{first_blocking, Keepout};
use generator::unseen_look::{UNSEEN_FAMILIES, UNSEEN_LIGHT_KINDS};
use grasp_schema::{Condition, SequencePlan};
use nalgebra::{UnitQuaternion, Vector3};

/// The conditions a training set (or its paper-style test sets) draws.
const TRAINING: [Condition; 5] = [
    Condition::Default,
    Condition::Fast,
    Condition::FromGround,
    Condition::Seated,
    Condition::Background,
];

fn plans(c: &GeneratorConfig, conditions: &[Condition], n: u32) -> Vec<SequencePlan> {
    let planner = carton_planner(c, 1.0);
    let mut out = Vec::new();
    for &cond in conditions {
        for i in 0..n {
            for part in ["top", "side"] {
                out.push(planner.plan(&key(part, i, cond)).unwrap());
            }
        }
    }
    out
}

fn range(values: impl Iterator<Item = f64>) -> [f64; 2] {
    values.fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], v| {
        [lo.min(v), hi.max(v)]
    })
}

fn disjoint(a: [f64; 2], b: [f64; 2]) -> bool {
    a[1] < b[0] || b[1] < a[0]
}

/// Every unseen_look value differs from every training value, on each axis.
fn assert_unseen_apart(c: &GeneratorConfig, n: u32) {
    let training = plans(c, &TRAINING, n);
    let unseen = plans(c, &[Condition::UnseenLook], 2 * n);
    let look = |p: &SequencePlan| p.appearance.clone().unwrap();
    // Texture families.
    for p in &training {
        let a = look(p);
        for f in [&a.wall.family, &a.floor.family, &a.table.family] {
            assert!(!UNSEEN_FAMILIES.contains(&f.as_str()), "training drew {f}");
        }
    }
    for p in &unseen {
        let a = look(p);
        for f in [&a.wall.family, &a.floor.family, &a.table.family] {
            assert!(UNSEEN_FAMILIES.contains(&f.as_str()), "unseen drew {f}");
        }
    }
    // Field of view.
    let fov = |ps: &[SequencePlan]| range(ps.iter().map(|p| p.intrinsics.fov_y_deg));
    let (t_fov, u_fov) = (fov(&training), fov(&unseen));
    assert!(disjoint(t_fov, u_fov), "FOV {t_fov:?} vs {u_fov:?}");
    // Lights: kinds, counts, colour temperatures.
    for p in &training {
        assert!(look(p)
            .lights
            .iter()
            .all(|l| !UNSEEN_LIGHT_KINDS.contains(&l.kind.as_str())));
    }
    for p in &unseen {
        assert!(look(p)
            .lights
            .iter()
            .all(|l| UNSEEN_LIGHT_KINDS.contains(&l.kind.as_str())));
    }
    let count = |ps: &[SequencePlan]| range(ps.iter().map(|p| look(p).lights.len() as f64));
    assert!(disjoint(count(&training), count(&unseen)));
    let kelvin = |ps: &[SequencePlan]| {
        range(
            ps.iter()
                .flat_map(|p| look(p).lights)
                .map(|l| l.color_temperature_k),
        )
    };
    assert!(disjoint(kelvin(&training), kelvin(&unseen)));
    // Environment light.
    for p in &training {
        if let (Some(w), true) = (look(p).world, c.randomize.world_light.enabled) {
            assert!(
                !c.appearance.unseen_look.hdris.contains(&w.hdri),
                "{}",
                w.hdri
            );
        }
    }
    // Tone mapping and exposure.
    for p in &training {
        assert_eq!(look(p).tone, None, "training keeps [render] view_transform");
    }
    for p in &unseen {
        let t = look(p).tone.unwrap();
        assert_ne!(t.view_transform, c.render.view_transform);
    }
    let exposure = |ps: &[SequencePlan]| range(ps.iter().map(|p| look(p).exposure));
    assert!(disjoint(exposure(&training), exposure(&unseen)));
    // Sensor effects: unseen noise levels and its defocus blur are its own.
    let noise = |ps: &[SequencePlan]| {
        range(
            ps.iter()
                .filter_map(|p| look(p).sensor.and_then(|s| s.noise_sigma)),
        )
    };
    assert!(disjoint(noise(&training), noise(&unseen)));
    for p in &training {
        let s = look(p).sensor;
        assert!(s.and_then(|s| s.blur_sigma_px).is_none());
    }
    for p in &unseen {
        assert!(look(p).sensor.unwrap().blur_sigma_px.unwrap() > 0.0);
    }
}

#[test]
fn unseen_look_values_never_occur_in_training_sets() {
    assert_unseen_apart(&GeneratorConfig::default(), 40);
}

#[test]
fn unseen_look_stays_apart_under_the_shipped_configs() {
    let root = generator::python::workspace_root().join("configs");
    for name in [
        "default.toml",
        "main-small.toml",
        "authors.toml",
        "test-sets.toml",
        "test-look-b.toml",
        "test-look-c.toml",
    ] {
        let mut c = GeneratorConfig::load(&root.join(name)).unwrap();
        // The carton planner needs the d435 camera's arm's-length starts.
        c.plan.camera = generator::plan::CameraConfig {
            resolution: c.plan.camera.resolution,
            ..Default::default()
        };
        c.plan.trajectory.standoff_m = 0.12;
        assert_unseen_apart(&c, 10);
    }
}

/// The values of one appearance axis drawn in a plan.
type Axis = fn(&SequencePlan) -> Vec<f64>;

fn appearance(p: &SequencePlan) -> &grasp_schema::appearance::Appearance {
    p.appearance.as_ref().unwrap()
}

/// A held-out look's unseen_look plans: the default unseen_look when `file`
/// is `None`, else the config in `configs/`.
fn held_out_look(file: Option<&str>) -> Vec<SequencePlan> {
    let root = generator::python::workspace_root().join("configs");
    let mut c = GeneratorConfig::load(&root.join("test-look-b.toml")).unwrap();
    c.appearance.unseen_look = match file {
        Some(f) => {
            GeneratorConfig::load(&root.join(f))
                .unwrap()
                .appearance
                .unseen_look
        }
        None => Default::default(),
    };
    c.plan.camera = generator::plan::CameraConfig {
        resolution: c.plan.camera.resolution,
        ..Default::default()
    };
    c.plan.trajectory.standoff_m = 0.12;
    plans(&c, &[Condition::UnseenLook], 20)
}

fn families(ps: &[SequencePlan]) -> std::collections::BTreeSet<String> {
    ps.iter()
        .flat_map(|p| {
            let l = appearance(p);
            [&l.wall.family, &l.floor.family, &l.table.family].map(String::clone)
        })
        .collect()
}

fn view_transform(ps: &[SequencePlan]) -> String {
    appearance(&ps[0]).tone.clone().unwrap().view_transform
}

/// Two held-out looks are apart on the given axes, and in their texture
/// families and view transform.
fn assert_looks_apart(a: &[SequencePlan], b: &[SequencePlan], axes: &[(&str, Axis)]) {
    assert!(
        families(a).is_disjoint(&families(b)),
        "{:?} vs {:?}",
        families(a),
        families(b)
    );
    assert_ne!(view_transform(a), view_transform(b));
    for (name, values) in axes {
        let r = |ps: &[SequencePlan]| range(ps.iter().flat_map(values));
        let (ra, rb) = (r(a), r(b));
        assert!(disjoint(ra, rb), "{name}: {ra:?} vs {rb:?}");
    }
}

const FOV: (&str, Axis) = ("fov", |p| vec![p.intrinsics.fov_y_deg]);
const LIGHTS: (&str, Axis) = ("lights", |p| vec![appearance(p).lights.len() as f64]);
const KELVIN: (&str, Axis) = ("kelvin", |p| {
    let lights = &appearance(p).lights;
    lights.iter().map(|l| l.color_temperature_k).collect()
});
const EXPOSURE: (&str, Axis) = ("exposure", |p| vec![appearance(p).exposure]);
const NOISE: (&str, Axis) = ("noise", |p| {
    let sensor = appearance(p).sensor.as_ref();
    sensor.and_then(|s| s.noise_sigma).into_iter().collect()
});

/// The second held-out look (`configs/test-look-b.toml`) is apart from the
/// default unseen_look on the axes it changes: families, lens, light count
/// and temperatures, tone mapping, exposure and noise.
#[test]
fn look_b_differs_from_the_default_unseen_look() {
    let (unseen, b) = (held_out_look(None), held_out_look(Some("test-look-b.toml")));
    assert_looks_apart(&unseen, &b, &[FOV, LIGHTS, KELVIN, EXPOSURE, NOISE]);
    assert_eq!(
        families(&b).into_iter().collect::<Vec<_>>(),
        ["mosaic", "rings"]
    );
    assert_eq!(view_transform(&b), "Filmic");
}

/// The third (`configs/test-look-c.toml`) is apart from both in families,
/// lens, light count and temperatures and tone mapping (its exposure and
/// noise lie between theirs and may meet them).
#[test]
fn look_c_differs_from_the_other_held_out_looks() {
    let c = held_out_look(Some("test-look-c.toml"));
    for other in [None, Some("test-look-b.toml")] {
        assert_looks_apart(&held_out_look(other), &c, &[FOV, LIGHTS, KELVIN]);
    }
    assert_eq!(
        families(&c).into_iter().collect::<Vec<_>>(),
        ["chevron", "triangles"]
    );
    assert_eq!(view_transform(&c), "Standard");
}

/// A config changed by `edit` must be refused with an error naming `field`.
fn refused(edit: impl Fn(&mut GeneratorConfig), field: &str) {
    let mut c = GeneratorConfig::default();
    edit(&mut c);
    let err = format!("{:#}", c.validate().unwrap_err());
    assert!(err.contains(field), "expected '{field}' in: {err}");
}

#[test]
fn validation_refuses_configs_where_training_meets_unseen_look() {
    refused(
        |c| c.appearance.families.push("dots".into()),
        "[appearance] families: 'dots' is reserved for the unseen_look",
    );
    refused(
        |c| c.appearance.light_kinds.push("sun".into()),
        "[appearance] light_kinds",
    );
    refused(
        |c| c.appearance.unseen_look.ring_lights = [1, 4],
        "overlaps the unseen_look light count",
    );
    refused(
        |c| c.appearance.unseen_look.color_temperature_k = [6000.0, 9000.0],
        "color_temperature_k",
    );
    refused(
        |c| c.appearance.color_temperature_k = [2700.0, 8000.0],
        "color_temperature_k",
    );
    refused(|c| c.randomize.fov.scale = [0.8, 1.4], "fov_scale");
    refused(
        |c| c.appearance.unseen_look.fov_scale = [0.9, 1.0],
        "fov_scale",
    );
    refused(
        |c| c.appearance.unseen_look.view_transform = "AgX".into(),
        "view_transform",
    );
    refused(
        |c| c.appearance.unseen_look.exposure = [-0.8, -0.2],
        "exposure",
    );
    refused(
        |c| c.randomize.sensor_noise.sigma = [0.0, 0.035],
        "noise_sigma",
    );
    refused(
        |c| c.randomize.world_light.hdris.push("courtyard".into()),
        "[randomize.world_light] hdris: 'courtyard'",
    );
    refused(
        |c| c.appearance.unseen_look.families = vec!["noise".into()],
        "[appearance.unseen_look] families: unknown 'noise'",
    );
    // With the FOV lever off training keeps the preset's lens (scale 1),
    // which an unseen range including 1 would meet.
    refused(
        |c| {
            c.randomize.fov.enabled = false;
            c.appearance.unseen_look.fov_scale = [0.95, 1.05];
        },
        "fov_scale",
    );
    GeneratorConfig::default().validate().unwrap();
}

#[test]
fn a_config_file_with_an_overlap_names_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, "[appearance]\nfamilies = [\"noise\", \"gabor\"]\n").unwrap();
    let err = format!(
        "{:#}",
        anyhow::Error::from(GeneratorConfig::load(&path).unwrap_err())
    );
    assert!(err.contains("bad.toml") && err.contains("gabor"), "{err}");
}

#[test]
fn new_values_reproduce_from_the_seed_and_land_in_the_plan() {
    let mut c = GeneratorConfig::default();
    c.randomize.world_light.probability = 1.0;
    c.randomize.jpeg.probability = 1.0;
    c.randomize.distractors.count = [2, 2];
    let a = plans(&c, &[Condition::Default, Condition::UnseenLook], 6);
    let b = plans(&c, &[Condition::Default, Condition::UnseenLook], 6);
    assert_eq!(
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap()
    );
    let mut other = c.clone();
    other.dataset.seed += 1;
    let o = plans(&other, &[Condition::Default], 6);
    assert_ne!(a[0].appearance, o[0].appearance);
    for p in &a {
        let json = serde_json::to_value(p).unwrap();
        let s = &json["sampled"];
        for k in [
            "standoff_m",
            "aim_offset",
            "target_end_forced",
            "fov_scale",
            "principal_point_shift",
            "distractor_count",
        ] {
            assert!(!s[k].is_null(), "{} lacks sampled.{k}", p.key.id());
        }
        let a = &json["appearance"];
        assert!(a["object"]["plausible"].is_boolean());
        assert!(a["world"]["hdri"].is_string() && a["world"]["strength"].is_number());
        assert!(a["sensor"]["noise_sigma"].is_number());
        if p.key.condition == Condition::UnseenLook {
            assert!(a["tone"]["view_transform"].is_string());
            assert!(a["sensor"]["blur_sigma_px"].is_number());
            assert!(a["motion_blur"].is_null());
        } else {
            assert!(a["motion_blur"]["shutter"].is_number());
            assert!(a["sensor"]["white_balance"].is_array());
            assert!(a["sensor"]["jpeg_quality"].is_number());
        }
        let k = &p.intrinsics;
        let scale = s["fov_scale"].as_f64().unwrap();
        let shift = s["principal_point_shift"].as_array().unwrap()[0]
            .as_f64()
            .unwrap();
        assert!((k.cx - f64::from(k.width) * (0.5 + shift)).abs() < 1e-9);
        let expect = (21f64.to_radians().tan() * scale).atan().to_degrees() * 2.0;
        assert!((k.fov_y_deg - expect).abs() < 1e-9);
    }
    // Some distractors were placed and sit on the table top.
    let placed: usize = a.iter().map(|p| p.distractors.len()).sum();
    assert!(
        placed >= a.len(),
        "{placed} distractors in {} plans",
        a.len()
    );
}

/// The plan with the values of one lever removed.
fn without(mut v: serde_json::Value, paths: &[&str]) -> serde_json::Value {
    for p in paths {
        let parts: Vec<&str> = p.split('.').collect();
        let mut node = &mut v;
        for k in &parts[..parts.len() - 1] {
            node = &mut node[*k];
        }
        if let Some(map) = node.as_object_mut() {
            map.remove(parts[parts.len() - 1]);
        }
    }
    v
}

#[test]
fn switching_a_lever_changes_only_its_own_values() {
    type Edit = fn(&mut GeneratorConfig);
    let cases: [(&str, Edit, &[&str]); 9] = [
        (
            "surface",
            |c| c.randomize.surface.enabled = false,
            &["appearance.object.surface"],
        ),
        (
            "world_light",
            |c| c.randomize.world_light.enabled = false,
            &["appearance.world"],
        ),
        (
            "motion_blur",
            |c| c.randomize.motion_blur.enabled = false,
            &["appearance.motion_blur"],
        ),
        (
            "white_balance",
            |c| c.randomize.white_balance.enabled = false,
            &["appearance.sensor.white_balance"],
        ),
        (
            "sensor_noise",
            |c| c.randomize.sensor_noise.enabled = false,
            &["appearance.sensor.noise_sigma"],
        ),
        (
            "jpeg",
            |c| c.randomize.jpeg.enabled = false,
            &["appearance.sensor.jpeg_quality"],
        ),
        (
            "object_color",
            |c| c.randomize.object_color.enabled = false,
            &["appearance.object.color", "appearance.object.plausible"],
        ),
        (
            "distractors",
            |c| c.randomize.distractors.enabled = false,
            &[
                "distractors",
                "sampled.distractor_count",
                "sampled.distractor_rejected_draws",
            ],
        ),
        (
            "principal_point",
            |c| c.randomize.principal_point.enabled = false,
            &[
                "intrinsics.cx",
                "intrinsics.cy",
                "sampled.principal_point_shift",
            ],
        ),
    ];
    let on = GeneratorConfig::default();
    let base = plans(&on, &TRAINING, 3);
    for (name, edit, paths) in cases {
        let mut off = on.clone();
        edit(&mut off);
        let other = plans(&off, &TRAINING, 3);
        let mut changed = false;
        for (a, b) in base.iter().zip(&other) {
            let (a, b) = (
                serde_json::to_value(a).unwrap(),
                serde_json::to_value(b).unwrap(),
            );
            changed |= a != b;
            // A sequence whose sensor effects all went away drops `sensor`.
            let (a, b) = (without(a, paths), without(b, paths));
            let strip = |mut v: serde_json::Value| {
                if v["appearance"]["sensor"]
                    .as_object()
                    .is_some_and(|m| m.keys().all(|k| k == "seed"))
                {
                    v["appearance"].as_object_mut().unwrap().remove("sensor");
                }
                v
            };
            assert_eq!(strip(a), strip(b), "lever {name} changed other values");
        }
        assert!(changed, "lever {name} changed nothing");
    }
}

#[test]
fn the_master_switch_turns_every_lever_off() {
    let mut c = GeneratorConfig::default();
    c.randomize.enabled = false;
    for p in plans(&c, &[Condition::Default], 10) {
        let a = p.appearance.unwrap();
        assert!(a.world.is_none() && a.motion_blur.is_none() && a.sensor.is_none());
        assert!(!a.object.plausible && a.object.surface.is_none() && p.distractors.is_empty());
        assert!((p.intrinsics.fov_y_deg - 42.0).abs() < 1e-9);
        assert_eq!(p.intrinsics.cx, 112.0);
        assert_eq!(p.sampled["standoff_m"], 0.12);
        assert_eq!(p.sampled["aim_offset"], serde_json::json!([0.0, 0.0]));
    }
}

#[test]
fn approach_ends_cover_both_ends_of_the_side_part() {
    let c = GeneratorConfig::default();
    let p = plans(&c, &[Condition::Default], 40);
    let ends = |part: &str, end: &str| {
        p.iter()
            .filter(|p| p.key.part == part && p.sampled["target_end"] == end)
            .count()
    };
    // Both ends of each part's approach axis are reached, in balance.
    for part in ["top", "side"] {
        let (plus, minus) = (ends(part, "+z"), ends(part, "-z"));
        assert!(plus >= 10 && minus >= 10, "{part}: +z {plus}, -z {minus}");
    }
    // Aim points lie on the target part's end face.
    for q in &p {
        let [u, v] = [0, 1].map(|i| q.sampled["aim_offset"][i].as_f64().unwrap());
        assert!(u.abs() <= 0.8 && v.abs() <= 0.8);
    }
}

/// The carton's bounding sphere (object frame: 8 x 8 x 16 cm, bottom at 0).
fn carton_keepout<'a>(p: &SequencePlan, path: &'a [Vector3<f64>]) -> Keepout<'a> {
    let q = p.object.pose.rotation_wxyz;
    let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
    let center = r * Vector3::new(0.0, 0.0, 0.08) + Vector3::from(p.object.pose.position);
    Keepout {
        object_center: center,
        object_radius: (0.04f64 * 0.04 * 2.0 + 0.08 * 0.08).sqrt(),
        path,
        target: Vector3::from(p.target),
    }
}

#[test]
fn distractors_never_overlap_the_target_or_block_the_reach() {
    let mut c = GeneratorConfig::default();
    c.randomize.distractors.count = [4, 6];
    c.randomize.distractors.size_m = [0.05, 0.2];
    let all = plans(&c, &TRAINING, 12);
    let mut placed = 0;
    for p in &all {
        let path: Vec<Vector3<f64>> = p
            .frames
            .iter()
            .map(|f| Vector3::from(f.camera.position))
            .collect();
        let k = carton_keepout(p, &path);
        assert_eq!(
            first_blocking(&p.distractors, &k, 0.0),
            None,
            "{}: a distractor meets the object or the reach",
            p.key.id()
        );
        let table = &c.plan.scene;
        for d in &p.distractors {
            let [x, y, z] = d.pose.position;
            assert!((z - table.table_height - d.size[2] / 2.0).abs() < 1e-12);
            assert!(x.abs() < table.table_size[0] / 2.0 && y.abs() < table.table_size[1] / 2.0);
        }
        // Pairwise apart.
        for (i, a) in p.distractors.iter().enumerate() {
            for b in &p.distractors[i + 1..] {
                let d = (Vector3::from(a.pose.position) - Vector3::from(b.pose.position)).xy();
                assert!(d.norm() > (a.size[0].min(a.size[1]) + b.size[0].min(b.size[1])) / 2.0);
            }
        }
        placed += p.distractors.len();
    }
    assert!(placed > all.len() * 2, "{placed} in {} plans", all.len());
    // The search itself is untouched: the same scene with and without them.
    let mut off = c.clone();
    off.randomize.distractors.enabled = false;
    for (a, b) in all.iter().zip(plans(&off, &TRAINING, 12)) {
        assert_eq!(a.frames, b.frames);
        assert_eq!(a.object, b.object);
    }
}

/// Objects are planned at the catalog's size: the lever that resized them
/// was measured twice, did not help and was deleted, so a config that still
/// names it is refused by name.
#[test]
fn objects_keep_the_catalog_size_and_the_deleted_resize_lever_is_refused() {
    for p in plans(&GeneratorConfig::default(), &[Condition::Default], 4) {
        assert_eq!(p.object.scale, 1.0);
        assert!(!p.sampled.contains_key("object_scale"));
    }
    let old = "[randomize.object_scale]\nenabled = true\n";
    let e = toml::from_str::<GeneratorConfig>(old)
        .unwrap_err()
        .to_string();
    assert!(e.contains("object_scale"), "{e}");
}

/// A planner for the carton read from a mesh file (a real object, as
/// `objects import-ycb` writes), not built procedurally.
fn file_mesh_planner(c: &GeneratorConfig) -> generator::plan::Planner {
    let (mut spec, mesh, body) = box_object(1.0);
    spec.mesh =
        serde_json::from_value(serde_json::json!({"file": {"path": "carton.ply"}})).unwrap();
    let geo = generator::plan::ObjectGeometry::new(
        spec,
        &mesh,
        Box::new(generator::plan::validity::BoxMesh(body)),
    )
    .unwrap();
    generator::plan::Planner::from_geometries(c, vec![geo]).unwrap()
}

/// `[randomize.proportions]` stretches the object along its frame's axes
/// with their product 1: the plan records the factors, the stretched
/// object rests on the table, and the target lies on an end face of the
/// catalog's part box once carried back into the catalog's frame. Off, or
/// for a mesh from a file, nothing is stretched or recorded.
#[test]
fn proportions_stretch_the_object_that_the_plan_checks_and_records() {
    let mut c = GeneratorConfig::default();
    c.randomize.proportions.enabled = true;
    c.randomize.proportions.spread = 0.3;
    let planner = carton_planner(&c, 1.0);
    let geo = planner.object("test_carton").unwrap();
    let table = c.plan.scene.table_height;
    let drawn = plans(&c, &[Condition::Default, Condition::UnseenLook], 6);
    for p in &drawn {
        let s = Vector3::from(p.object.proportions);
        assert_eq!(p.object.scale, 1.0);
        assert!((s.product() - 1.0).abs() < 1e-12, "{}: {s:?}", p.key.id());
        assert!(s.iter().all(|f| (1.0 / 1.3 / 1.3..=1.3 * 1.3).contains(f)));
        let recorded: Vec<f64> = serde_json::from_value(p.sampled["proportions"].clone()).unwrap();
        assert_eq!(recorded, s.as_slice());
        // The stretched object rests on the table top.
        let q = generator::plan::wrist::from_wxyz(p.object.pose.rotation_wxyz);
        let z = p.object.pose.position[2];
        let lowest = if p.object.upside_down {
            -geo.z_range[1] * s.z
        } else {
            geo.z_range[0] * s.z
        };
        assert!((z - (table - lowest)).abs() < 1e-9, "{}", p.key.id());
        // The target lies on an end face of the catalog's part box (the
        // carton's boxes are the frame's), once carried back.
        let t = Vector3::from(p.target) - Vector3::from(p.object.pose.position);
        let local = q.inverse_transform_vector(&t).component_div(&s);
        let b = &geo.boxes[p.part_index];
        let in_box = b.rotation.inverse_transform_vector(&(local - b.center));
        assert!(
            (in_box.z.abs() - b.half.z).abs() < 1e-9,
            "{}: {in_box:?}",
            p.key.id()
        );
        assert!(in_box.x.abs() <= b.half.x + 1e-9 && in_box.y.abs() <= b.half.y + 1e-9);
    }
    let x: Vec<f64> = drawn.iter().map(|p| p.object.proportions[0]).collect();
    let [low, high] = range(x.iter().copied());
    assert!(high - low > 0.1, "{x:?}");
    let mut off = c.clone();
    off.randomize.proportions.enabled = false;
    for p in plans(&off, &[Condition::Default], 4) {
        assert_eq!(p.object.axis_scale(), [1.0; 3]);
        assert!(!p.sampled.contains_key("proportions"));
    }
    // A mesh from a file (a real object, as `objects import-ycb` writes) is
    // never stretched, with the lever on.
    let real = file_mesh_planner(&c);
    for i in 0..4 {
        let p = real.plan(&key("side", i, Condition::Default)).unwrap();
        assert_eq!(p.object.axis_scale(), [1.0; 3]);
        assert!(!p.sampled.contains_key("proportions"));
    }
    refused(
        |c| c.randomize.proportions.spread = 1.5,
        "[randomize.proportions] spread",
    );
    refused(
        |c| c.randomize.proportions.spread = f64::NAN,
        "[randomize.proportions] spread",
    );
}

/// `[randomize.surface]` draws a surface for procedural objects from its
/// own stream: every plan has `appearance.object.surface` within the
/// ranges, and switched off nothing else changes; a mesh from a file keeps
/// its own surface; bad ranges are refused by name.
#[test]
fn surface_rounds_and_roughens_procedural_objects_only() {
    let on = GeneratorConfig::default();
    assert!(on.randomize.surface.enabled);
    let mut off = on.clone();
    off.randomize.surface.enabled = false;
    let conditions = [Condition::Default, Condition::UnseenLook];
    let (before, after) = (plans(&off, &conditions, 4), plans(&on, &conditions, 4));
    let mut radii = Vec::new();
    for (a, b) in before.iter().zip(&after) {
        assert_eq!(appearance(a).object.surface, None);
        let s = appearance(b)
            .object
            .surface
            .expect("a surface with the lever on");
        assert!((0.0..=0.004).contains(&s.edge_radius_m), "{s:?}");
        assert!((0.0..=0.3).contains(&s.relief), "{s:?}");
        assert!((0.002..=0.02 + 1e-12).contains(&s.relief_size_m), "{s:?}");
        radii.push(s.edge_radius_m);
        let mut b = b.clone();
        b.appearance.as_mut().unwrap().object.surface = None;
        assert_eq!(a, &b, "only the surface changes");
    }
    let [low, high] = range(radii.into_iter());
    assert!(high - low > 0.001, "radii {low}..{high}");
    let real = file_mesh_planner(&on);
    for i in 0..4 {
        let p = real.plan(&key("side", i, Condition::Default)).unwrap();
        assert_eq!(appearance(&p).object.surface, None);
    }
    refused(
        |c| c.randomize.surface.relief = [0.0, 1.5],
        "[randomize.surface] relief",
    );
    refused(
        |c| c.randomize.surface.edge_radius_m = [-0.001, 0.004],
        "[randomize.surface] edge_radius_m",
    );
    refused(
        |c| c.randomize.surface.relief_size_m = [0.0, 0.01],
        "[randomize.surface] relief_size_m",
    );
}

/// A held-out test world (`[dataset] held_out`, configs/test-world-reach.toml)
/// is recorded in every plan, so training can refuse it; without one the
/// plans carry no such key, and the mark changes no other value.
#[test]
fn a_held_out_world_is_recorded_in_every_plan_and_changes_nothing_else() {
    let base = GeneratorConfig::default();
    let mut marked = base.clone();
    marked.dataset.held_out = Some("reach".into());
    let own = plans(&base, &[Condition::Default], 2);
    let held = plans(&marked, &[Condition::Default], 2);
    for (p, mut h) in own.into_iter().zip(held) {
        assert!(!p.sampled.contains_key("held_out"));
        assert_eq!(
            h.sampled.remove("held_out"),
            Some(serde_json::json!("reach"))
        );
        assert_eq!(p, h);
    }
    // The reach world's own config: closer ends than any training reach.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    let reach = GeneratorConfig::load_layers(
        &[dir.join("main.toml"), dir.join("test-world-reach.toml")],
        &[],
    )
    .unwrap();
    assert_eq!(reach.dataset.held_out.as_deref(), Some("reach"));
    let standoff = |c: &GeneratorConfig| {
        range(
            plans(c, &[Condition::Default], 2)
                .iter()
                .map(|p| p.sampled["standoff_m"].as_f64().unwrap()),
        )
    };
    let (train, test) = (standoff(&base), standoff(&reach));
    assert!(test[1] < train[0], "reach {test:?} vs training {train:?}");
    // Seen at another frame rate than the main job's training set.
    let main = GeneratorConfig::load_layers(&[dir.join("main.toml")], &[]).unwrap();
    assert_eq!(reach.plan.trajectory.fps, 2.0 * main.plan.trajectory.fps);
}

/// The camera world (`configs/test-world-camera.toml`): a 4:3 image behind a
/// 69-degree lens, a seated reach, and a handheld shake that moves only the
/// camera's poses (drawn from its own sub-stream) and is recorded.
#[test]
fn the_camera_world_has_a_wide_4_by_3_lens_and_shakes_only_the_camera() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    let camera = GeneratorConfig::load_layers(
        &[dir.join("main.toml"), dir.join("test-world-camera.toml")],
        &[],
    )
    .unwrap();
    assert_eq!(camera.dataset.held_out.as_deref(), Some("camera"));
    assert_eq!(camera.dataset.conditions, [Condition::Seated]);
    let mut still = camera.clone();
    still.plan.shake.enabled = false;
    let shaken = plans(&camera, &[Condition::Seated], 2);
    let calm = plans(&still, &[Condition::Seated], 2);
    assert!(!shaken.is_empty());
    for (mut s, c) in shaken.into_iter().zip(calm) {
        let k = &s.intrinsics;
        assert_eq!((k.width, k.height), (320, 240));
        assert!((k.fov_x_deg - 69.0).abs() < 0.5, "{k:?}");
        let record = s.sampled.remove("shake").expect("the shake is recorded");
        assert!(record["rotation"].is_array(), "{record}");
        let mut turned = 0.0f64;
        for (a, b) in s.frames.iter_mut().zip(&c.frames) {
            let dot: f64 = (0..4)
                .map(|i| a.camera.rotation_wxyz[i] * b.camera.rotation_wxyz[i])
                .sum();
            turned = turned.max(2.0 * dot.abs().min(1.0).acos().to_degrees());
            let moved: f64 = (0..3)
                .map(|i| (a.camera.position[i] - b.camera.position[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(moved < 0.02, "a shake of millimetres, not {moved} m");
            a.camera = b.camera;
        }
        assert!(
            turned > 0.2 && turned < 8.0,
            "largest turn {turned} degrees"
        );
        assert_eq!(s, c, "only the camera's poses change");
    }
    refused(
        |c| c.plan.shake.rotation_deg = f64::NAN,
        "plan.shake.rotation_deg",
    );
}

/// The fourth held-out look (`configs/test-look-d.toml`) has a lens and
/// light temperatures apart from the other three; its families are one of
/// look B's and one of look C's.
#[test]
fn look_d_differs_from_the_other_held_out_looks_in_lens_and_light() {
    let d = held_out_look(Some("test-look-d.toml"));
    for other in [None, Some("test-look-b.toml"), Some("test-look-c.toml")] {
        let o = held_out_look(other);
        for (name, values) in [FOV, KELVIN] {
            let r = |ps: &[SequencePlan]| range(ps.iter().flat_map(values));
            assert!(disjoint(r(&o), r(&d)), "{name} vs {other:?}");
        }
    }
    assert_eq!(
        families(&d).into_iter().collect::<Vec<_>>(),
        ["mosaic", "triangles"]
    );
}
