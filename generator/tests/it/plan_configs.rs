//! The shipped configs parse, and configs/default.toml states the defaults.

use generator::config::GeneratorConfig;
use generator::plan::camera::CameraPreset;
use std::path::Path;

fn load(name: &str) -> GeneratorConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../configs")
        .join(name);
    GeneratorConfig::load(&path).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

#[test]
fn default_toml_is_the_built_in_default() {
    let c = load("default.toml");
    let d = GeneratorConfig::default();
    assert_eq!(c.dataset, d.dataset);
    assert_eq!(c.plan, d.plan);
    assert_eq!(c.appearance, d.appearance);
    assert_eq!(c.randomize, d.randomize);
    c.plan.validate().unwrap();
}

#[test]
fn example_configs_parse_and_validate() {
    let a = load("authors.toml");
    assert_eq!(a.plan.camera.preset, CameraPreset::Authors);
    assert!((a.plan.camera.intrinsics().fov_y_deg - 7.0).abs() < 1e-9);
    a.plan.validate().unwrap();
    let t = load("test-sets.toml");
    assert_eq!(t.dataset.conditions.len(), 6);
}

#[test]
fn a_bad_value_names_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(
        &path,
        "[plan.trajectory]\nduration_s = 3.0\nfps = 30.0\nno_grasp_tail = 0.5\n",
    )
    .unwrap();
    let err = format!(
        "{:#}",
        anyhow::Error::from(GeneratorConfig::load(&path).unwrap_err())
    );
    assert!(
        err.contains("bad.toml") && err.contains("no_grasp_tail"),
        "{err}"
    );
    // A value out of range is refused on load, naming the file and field.
    std::fs::write(&path, "[plan.trajectory]\nno_grasp_tail_s = 5.0\n").unwrap();
    let err = format!(
        "{:#}",
        anyhow::Error::from(GeneratorConfig::load(&path).unwrap_err())
    );
    assert!(
        err.contains("bad.toml") && err.contains("plan.trajectory.no_grasp_tail_s"),
        "{err}"
    );
}
