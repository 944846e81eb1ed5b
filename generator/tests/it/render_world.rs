//! `[render] world`: the foreign world renders the same plans and labels
//! as the studio, records `render.world = "foreign"` in every
//! `sequence.json`, and draws other pixels (lit, not black, the same bytes
//! with one worker or two); a dataset of
//! one world is refused as the other's (`--resume`, `dataset verify
//! --config`); and configs the foreign world cannot render are refused
//! naming the field. Cycles, 1 sample, 48 px, the built-in mug's body and
//! handle, three frames each.

use crate::render_common::*;
use generator::config::GeneratorConfig;
use std::path::{Path, PathBuf};

/// A tiny Cycles config of the mug's body and handle in `world`.
fn config(dir: &Path, world: &str) -> PathBuf {
    let text = format!(
        "[dataset]\nsequences_per_pair = 1\nconditions = [\"default\"]\n\
         parts = [\"025_mug/body\", \"025_mug/handle\"]\n\n\
         [plan.camera]\nresolution = [48, 48]\n\n[plan.trajectory]\nfps = 1.0\n\n\
         [render]\nworld = \"{world}\"\nengine = \"cycles\"\nsamples = 1\ndevice = \"cpu\"\n\
         threads = 1\n"
    );
    let path = dir.join(format!("{world}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

fn render(cfg: &Path, out: &Path, workers: &str) {
    grasp_gen().ok([
        "render",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--workers",
        workers,
        "--no-progress",
    ]);
}

/// Mean of a frame's 8-bit values, and the mean absolute difference of two.
fn mean(img: &image::RgbImage) -> f64 {
    img.as_raw().iter().map(|&v| f64::from(v)).sum::<f64>() / img.as_raw().len() as f64
}

fn mean_abs_diff(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    let (a, b) = (a.as_raw(), b.as_raw());
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).abs())
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn the_foreign_world_draws_the_studios_plans_with_other_pixels() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for world in ["studio", "foreign"] {
        let (cfg, out) = (config(dir.path(), world), dir.path().join(world));
        render(&cfg, &out, "1");
        outs.push((cfg, out));
    }
    // Its draws and noise follow the sequence, not the worker: one and two
    // workers give the same bytes.
    let again = dir.path().join("foreign-2");
    render(&outs[1].0, &again, "2");
    let (one, two) = (tree(&outs[1].1), tree(&again));
    let pngs: Vec<_> = one.keys().filter(|n| n.ends_with(".png")).collect();
    assert_eq!(pngs.len(), 6, "two sequences of three frames");
    for name in pngs {
        assert!(
            one[name] == two[name],
            "{name} differs between 1 and 2 workers"
        );
    }
    let (studio, foreign) = (records(&outs[0].1), records(&outs[1].1));
    assert_eq!(studio.len(), 2, "the mug's body and handle");
    assert_eq!(studio.len(), foreign.len());
    for ((path, a), (other, b)) in studio.iter().zip(&foreign) {
        assert_eq!(path, other);
        assert!(a.plan == b.plan, "{}: plans differ", path.display());
        assert_eq!(a.plan.labels(), b.plan.labels());
        assert_eq!(a.frame_files, b.frame_files);
        assert_eq!(a.render["world"], "studio");
        assert_eq!(b.render["world"], "foreign");
        assert_eq!(a.world().as_deref(), Some("studio"));
        assert_eq!(b.world().as_deref(), Some("foreign"));
        let folder = path.parent().unwrap();
        for name in &a.frame_files {
            let read = |root: &Path| image::open(root.join(folder).join(name)).unwrap().to_rgb8();
            let (s, f) = (read(&outs[0].1), read(&outs[1].1));
            assert_eq!(s.dimensions(), f.dimensions());
            let m = mean(&f);
            assert!(
                m > 15.0 && m < 240.0,
                "{name} of {}: a foreign frame is black or blown out (mean {m:.1})",
                folder.display()
            );
            let d = mean_abs_diff(&s, &f);
            assert!(
                d > 8.0,
                "{name} of {}: the worlds' frames barely differ ({d:.1})",
                folder.display()
            );
        }
    }
    // Each dataset verifies against its own config, and the other world's
    // config names the difference; --resume refuses to mix the worlds.
    for (i, (cfg, data)) in outs.iter().enumerate() {
        let stdout = grasp_gen()
            .ok([
                "dataset",
                "verify",
                data.to_str().unwrap(),
                "--config",
                cfg.to_str().unwrap(),
            ])
            .stdout;
        assert!(stdout.trim_end().ends_with("ok"), "{stdout}");
        let other = &outs[1 - i].0;
        let out = grasp_gen().run([
            "render",
            "--config",
            other.to_str().unwrap(),
            "--out",
            data.to_str().unwrap(),
            "--resume",
            "--no-progress",
        ]);
        let text = out.stderr + &out.stdout;
        assert!(!out.status.success(), "{text}");
        assert!(text.contains("[render] world"), "{text}");
    }
}

#[test]
fn a_foreign_world_config_it_cannot_render_is_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("foreign.toml");
    let refused = |text: &str, wanted: &[&str]| {
        std::fs::write(&path, text).unwrap();
        let e = format!(
            "{:#}",
            anyhow::Error::from(GeneratorConfig::load(&path).unwrap_err())
        );
        assert!(e.contains("foreign.toml"), "{e}");
        for w in wanted {
            assert!(e.contains(w), "{w} not in: {e}");
        }
    };
    refused(
        "[render]\nworld = \"foreign\"\nengine = \"workbench\"\n",
        &["[render] world = \"foreign\"", "engine"],
    );
    refused(
        "[render]\nworld = \"foreign\"\npasses = [\"rgb\", \"part\"]\n",
        &["[render] world = \"foreign\"", "passes"],
    );
    refused(
        "[plan.head_camera]\nenabled = true\n\n[render]\nworld = \"foreign\"\n",
        &["[render] world = \"foreign\"", "[plan.head_camera] enabled"],
    );
    refused("[render]\nworld = \"mars\"\n", &["world", "mars", "studio"]);
    std::fs::write(&path, "[render]\nworld = \"foreign\"\n").unwrap();
    let c = GeneratorConfig::load(&path).unwrap();
    assert_eq!(c.render.world.name(), "foreign");
    assert!(!c.render.world.trainable());
    assert_eq!(c.render.blender_settings()["world"], "foreign");
    let studio = GeneratorConfig::default();
    assert!(studio.render.world.trainable());
    assert_eq!(studio.render.blender_settings()["world"], "studio");
}

/// The shipped config renders the main job's default test set (the same
/// seed, plans and labels as `test-default`) in the foreign world.
#[test]
fn the_foreign_world_config_is_the_main_test_sets_plans() {
    let root = generator::python::workspace_root();
    let c = GeneratorConfig::load(&root.join("configs/test-world-foreign.toml")).unwrap();
    let main = GeneratorConfig::load(&root.join("configs/main.toml")).unwrap();
    assert_eq!(c.render.world.name(), "foreign");
    assert_eq!(c.dataset.seed, 3, "the main job's test seed");
    assert_eq!(c.dataset.sequences_per_pair, 2);
    assert_eq!(c.plan, main.plan, "plans as the main job's test sets");
    assert_eq!(c.appearance, main.appearance);
    assert_eq!(c.randomize, main.randomize);
}
