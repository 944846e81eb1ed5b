//! Real Blender renders of the new looks: one tiny `unseen_look` sequence
//! and one tiny training sequence with every lever on (Cycles, 1 sample),
//! and the image-space effects reproducing byte for byte (Workbench).

use crate::render_common::*;
use generator::config::GeneratorConfig;
use generator::render::{planner_source, render, Engine, RenderConfig};
use grasp_schema::appearance::{ObjectSurface, SensorEffects};
use grasp_schema::dataset::SequenceRecord;
use std::sync::Arc;

fn records(root: &std::path::Path) -> Vec<(std::path::PathBuf, SequenceRecord)> {
    generator::dataset::writer::find_sequences(root)
        .unwrap()
        .into_iter()
        .map(|(rel, r)| (root.join(rel), r))
        .collect()
}

#[test]
fn unseen_look_and_every_training_lever_render() {
    if !have_blender() {
        return;
    }
    let mut c = GeneratorConfig::default();
    c.dataset.seed = 3;
    c.dataset.sequences_per_pair = 1;
    c.dataset.conditions = vec![
        grasp_schema::Condition::Default,
        grasp_schema::Condition::UnseenLook,
    ];
    c.dataset.objects = Some(vec!["025_mug".into()]);
    c.dataset.parts = Some(vec!["handle".into()]);
    c.plan.camera.resolution = [48, 48];
    c.plan.trajectory.fps = 1.0;
    c.randomize.world_light.probability = 1.0;
    c.randomize.jpeg.probability = 1.0;
    c.randomize.distractors.count = [2, 2];
    c.randomize.surface.enabled = true;
    c.render = RenderConfig {
        samples: 1,
        ..Default::default()
    };
    c.validate().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let source = planner_source::from_config(&c).unwrap();
    let s = render(source, &c.render, &options(dir.path(), 1)).unwrap();
    assert_eq!((s.rendered, s.failed.len()), (2, 0), "{s:?}");
    let all = records(dir.path());
    assert_eq!(all.len(), 2);
    for (folder, r) in &all {
        let a = r.plan.appearance.as_ref().unwrap();
        let cost = r.render_cost().unwrap();
        assert!(cost.effects_seconds > 0.0, "effects are timed");
        assert!(cost.camera_seconds["Wrist_d435"] >= cost.effects_seconds);
        for f in &r.frame_files {
            let img = image::open(folder.join(f)).unwrap().to_rgb8();
            assert_eq!(img.dimensions(), (48, 48));
            let first = *img.get_pixel(0, 0);
            assert!(img.pixels().any(|p| *p != first), "a uniform frame");
        }
        let sensor = a.sensor.as_ref().unwrap();
        if r.plan.key.condition == grasp_schema::Condition::UnseenLook {
            assert_eq!(
                a.tone.as_ref().unwrap().view_transform,
                "Khronos PBR Neutral"
            );
            assert_eq!(a.lights[0].kind, "sun");
            assert!(sensor.blur_sigma_px.is_some() && sensor.jpeg_quality.is_none());
            assert!(a.motion_blur.is_none());
        } else {
            assert!(a.world.is_some() && a.motion_blur.is_some());
            assert!(sensor.white_balance.is_some() && sensor.jpeg_quality.is_some());
            assert!(a.object.plausible || a.object.randomized);
            assert!(a.object.surface.is_some());
            assert_eq!(r.plan.distractors.len(), 2);
        }
    }
    // The render settings recorded with the frames name the engine.
    assert_eq!(all[0].1.render["engine"], "cycles");
}

/// The hand-made sequences of `render_common` with camera effects on.
fn with_effects(effects: Option<SensorEffects>) -> generator::render::source::StaticSource {
    let mut src = source(2, 3, 40);
    for p in &mut src.plans {
        p.appearance.as_mut().unwrap().sensor = effects.clone();
    }
    src
}

#[test]
fn camera_effects_reproduce_byte_for_byte() {
    if !have_blender() {
        return;
    }
    let effects = SensorEffects {
        seed: 99,
        white_balance: Some([1.15, 1.0, 0.85]),
        blur_sigma_px: Some(0.7),
        noise_sigma: Some(0.02),
        jpeg_quality: Some(60),
    };
    let cfg = RenderConfig {
        engine: Engine::Workbench,
        samples: 1,
        ..Default::default()
    };
    let (a, b, plain) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    for dir in [&a, &b] {
        let src = Arc::new(with_effects(Some(effects.clone())));
        render(src, &cfg, &options(dir.path(), 1)).unwrap();
    }
    render(
        Arc::new(with_effects(None)),
        &cfg,
        &options(plain.path(), 1),
    )
    .unwrap();
    let (ta, tb, tp) = (tree(a.path()), tree(b.path()), tree(plain.path()));
    assert_eq!(ta, tb, "same plan, same bytes");
    let frames = |t: &std::collections::BTreeMap<String, Vec<u8>>| -> Vec<Vec<u8>> {
        t.iter()
            .filter(|(k, _)| k.ends_with(".png"))
            .map(|(_, v)| v.clone())
            .collect()
    };
    let (fa, fp) = (frames(&ta), frames(&tp));
    assert_eq!(fa.len(), 6);
    assert!(
        fa.iter().zip(&fp).all(|(x, y)| x != y),
        "every frame carries the effects"
    );
}

/// The RGB of both frames of one a_box sequence (64 px) with `surface` on
/// the object.
fn render_surface(config: &RenderConfig, surface: Option<ObjectSurface>) -> Vec<Vec<u8>> {
    let mut src = source(1, 2, 64);
    src.plans.truncate(1);
    src.plans[0].appearance.as_mut().unwrap().object.surface = surface;
    let dir = tempfile::tempdir().unwrap();
    let s = render(Arc::new(src), config, &options(dir.path(), 1)).unwrap();
    assert_eq!((s.rendered, s.failed.len()), (1, 0), "{s:?}");
    let (folder, r) = records(dir.path()).remove(0);
    r.frame_files
        .iter()
        .map(|f| image::open(folder.join(f)).unwrap().to_rgb8().into_raw())
        .collect()
}

/// Channel values that differ by more than 8 grey levels.
fn changed(a: &[Vec<u8>], b: &[Vec<u8>]) -> usize {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .filter(|(x, y)| x.abs_diff(**y) > 8)
        .count()
}

/// `[randomize.surface]` reaches the render: a zero radius and relief draw
/// the model as built, to the byte; a 2 cm radius rounds the box's edges
/// (Workbench draws the geometry), and a relief roughens its shading
/// (Cycles draws the shader's bump). Ignored by Blender, both would match.
#[test]
fn rounded_edges_and_relief_reach_the_render() {
    if !have_blender() {
        return;
    }
    let surface = |edge_radius_m, relief| ObjectSurface {
        edge_radius_m,
        relief,
        relief_size_m: 0.01,
    };
    let wb = workbench();
    let built = render_surface(&wb, None);
    assert_eq!(built, render_surface(&wb, Some(surface(0.0, 0.0))));
    let rounded = changed(&built, &render_surface(&wb, Some(surface(0.02, 0.0))));
    assert!(rounded > 30, "rounded edges changed {rounded} values");

    let cycles = RenderConfig {
        engine: Engine::Cycles,
        samples: 4,
        denoiser: "none".into(),
        ..Default::default()
    };
    let smooth = render_surface(&cycles, Some(surface(0.0, 0.0)));
    assert_eq!(smooth, render_surface(&cycles, None), "Cycles repeats");
    let relief = changed(&smooth, &render_surface(&cycles, Some(surface(0.0, 1.0))));
    assert!(relief > 100, "the relief changed {relief} values");
}
