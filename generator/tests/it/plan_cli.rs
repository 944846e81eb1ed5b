//! `grasp-gen plan` end to end: JSON lines, the picture, errors.

use grasp_test_support::Program;
use std::process::Command;

fn grasp_gen() -> Command {
    Program::new(env!("CARGO_BIN_EXE_grasp-gen")).command(std::iter::empty::<&str>())
}

#[test]
fn plan_writes_json_lines_and_a_picture() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("c.toml");
    std::fs::write(
        &config,
        "[dataset]\nsequences_per_pair = 3\nobjects = [\"025_mug\", \"048_hammer\"]\nconditions = [\"default\", \"from_ground\"]\n",
    )
    .unwrap();
    let out = dir.path().join("plans.jsonl");
    let png = dir.path().join("paths.png");
    let status = grasp_gen()
        .args(["plan", "--quiet", "--config"])
        .arg(&config)
        .arg("--out")
        .arg(&out)
        .arg("--show")
        .arg(&png)
        .status()
        .unwrap();
    assert!(status.success());
    let plans = generator::plan::cli::read_jsonl(&out).unwrap();
    // The mug has 4 parts and the hammer 1: 5 pairs x 2 conditions x 3.
    assert_eq!(plans.len(), 30);
    assert!(!dir.path().join(".plans.jsonl.tmp").exists());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    let img = image::open(&png).unwrap();
    assert!(img.width() > 400 && img.height() > 300);
    // Same config, same bytes.
    let again = dir.path().join("again.jsonl");
    let status = grasp_gen()
        .args(["plan", "--quiet", "--config"])
        .arg(&config)
        .arg("--out")
        .arg(&again)
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
}

#[test]
fn plan_errors_name_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let nothing = grasp_gen().arg("plan").output().unwrap();
    assert!(!nothing.status.success());
    assert!(String::from_utf8_lossy(&nothing.stderr).contains("--out"));
    let config = dir.path().join("bad.toml");
    std::fs::write(&config, "[plan.camera]\npreset = \"gopro\"\n").unwrap();
    let bad = grasp_gen()
        .args(["plan", "--config"])
        .arg(&config)
        .arg("--out")
        .arg(dir.path().join("x.jsonl"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("bad.toml") && err.contains("gopro"), "{err}");
    assert!(!dir.path().join("x.jsonl").exists());
}
