//! Configs that cannot work are refused before anything is planned or
//! rendered, naming the field (issue 15, items 7 and 8): sizes that would
//! exhaust memory (7.5 million frames per sequence, a billion sequences per
//! pair, 100000-pixel frames) and object ids or parts that are not in the
//! catalog. `plan`, `render` and `dataset verify --config` agree.
//!
//! The commands run under a 6 GB address-space limit, so a regression fails
//! with an allocation error instead of taking the machine's memory.

use crate::render_common::{exe, have_blender};
use std::path::{Path, PathBuf};
use std::process::Command;

const TINY: &str = "[plan.camera]\nresolution = [32, 32]\n\n[render]\nengine = \"workbench\"\n\
                    samples = 1\n";

fn write_config(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs `grasp-gen ARGS` under the memory limit; (success, stdout + stderr).
fn limited(args: &[&str]) -> (bool, String) {
    let mut script = String::from("ulimit -v 6000000; exec \"$0\"");
    for i in 1..=args.len() {
        script.push_str(&format!(" \"${i}\""));
    }
    let out = Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(exe())
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// `plan`, `render` and `dataset verify --config` all refuse `config` with
/// a message holding every `needle`, and `render` writes nothing.
fn refused_everywhere(dir: &Path, config: &Path, needles: &[&str]) {
    let cfg = config.to_str().unwrap();
    let out = dir.join("out");
    let plans = dir.join("plans.jsonl");
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let runs: [&[&str]; 3] = [
        &["plan", "--config", cfg, "--out", plans.to_str().unwrap()],
        &["render", "--config", cfg, "--out", out.to_str().unwrap()],
        &["dataset", "verify", data.to_str().unwrap(), "--config", cfg],
    ];
    for args in runs {
        let (ok, text) = limited(args);
        assert!(!ok, "{args:?} accepted the config:\n{text}");
        for needle in needles {
            assert!(
                text.contains(needle),
                "{args:?}: '{needle}' missing:\n{text}"
            );
        }
        assert!(
            !text.contains("memory allocation") && !text.contains("GPU"),
            "{args:?}: {text}"
        );
    }
    assert!(!out.exists(), "render wrote {}", out.display());
    assert!(!plans.exists(), "plan wrote {}", plans.display());
}

#[test]
fn sizes_that_cannot_fit_are_refused_naming_the_field() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str]); 4] = [
        (
            "[dataset]\nsequences_per_pair = 1000000000\n",
            &[
                "dataset.sequences_per_pair = 1000000000",
                "the limit is 1000000",
            ],
        ),
        (
            // 3 s at 2.5 MHz: 7.5 million frames per sequence.
            "[plan.trajectory]\nfps = 2500000.0\n",
            &["7500000 frames per default sequence", "the limit is 100000"],
        ),
        (
            "[plan.camera]\nresolution = [100000, 100000]\n",
            &["plan.camera.resolution = [100000, 100000]", "the limit is"],
        ),
        (
            "[dataset]\nconditions = [\"fast\"]\n[plan.camera]\nresolution = [4096, 4096]\n\
             [plan.trajectory]\nfps = 100.0\n",
            &[
                "plan.camera.resolution x frames",
                "fast sequence has 150 frames",
            ],
        ),
    ];
    for (i, (text, needles)) in cases.iter().enumerate() {
        let case = dir.path().join(format!("case{i}"));
        std::fs::create_dir_all(&case).unwrap();
        let mut full = (*text).to_string();
        if !text.contains("[plan.camera]") {
            full.push_str(TINY);
        }
        let cfg = write_config(&case, "big.toml", &full);
        refused_everywhere(&case, &cfg, needles);
    }
}

#[test]
fn an_unknown_object_or_part_is_refused_with_near_matches() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_config(
        dir.path(),
        "typo.toml",
        &format!("[dataset]\nsequences_per_pair = 1\nobjects = [\"025_mugg\"]\n{TINY}"),
    );
    refused_everywhere(
        dir.path(),
        &cfg,
        &["unknown object id '025_mugg'", "did you mean '025_mug'?"],
    );
    let cfg = write_config(
        dir.path(),
        "part.toml",
        &format!(
            "[dataset]\nsequences_per_pair = 1\nobjects = [\"025_mug\"]\n\
             parts = [\"025_mug/handel\"]\n{TINY}"
        ),
    );
    refused_everywhere(
        dir.path(),
        &cfg,
        &["no part '025_mug/handel'", "did you mean '025_mug/handle'"],
    );
}

#[test]
fn a_center_region_of_less_than_a_few_pixels_is_refused_naming_the_field() {
    // Issue 60, case 5: 1e-9 passed validation and failed inside Blender.
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for value in ["1e-9", "0.1"] {
        let case = dir.path().join(value);
        std::fs::create_dir_all(&case).unwrap();
        let text = TINY.replace(
            "[render]\n",
            &format!("[render]\ncenter_region = {value}\n"),
        );
        let cfg = write_config(&case, "small.toml", &text);
        refused_everywhere(
            &case,
            &cfg,
            &["[render] center_region", "at least 8 pixels"],
        );
    }
}
