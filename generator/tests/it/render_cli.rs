//! End to end through the CLI with the built-in catalog and the real planner:
//! all 31 pairs rendered and verified, a run killed (SIGKILL) midway and
//! resumed, and the preview. Workbench, 32 px, 2 to 3 frames per sequence.

use crate::render_common::{grasp_gen, have_blender, tree};
use std::path::Path;
use std::process::Stdio;
use std::time::Duration;

fn config(dir: &Path, objects: Option<&str>) -> std::path::PathBuf {
    let objects = objects
        .map(|o| format!("objects = [{o}]\n"))
        .unwrap_or_default();
    let text = format!(
        "[dataset]\nsequences_per_pair = 1\nconditions = [\"default\"]\n{objects}\n\
         [plan.camera]\nresolution = [32, 32]\n\n[plan.trajectory]\nfps = 1.0\n\n\
         [render]\nengine = \"workbench\"\nsamples = 1\n"
    );
    let path = dir.join("tiny.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// About 10 to 30 seconds on 2 cores (31 sequences of 3 frames at 32 px).
#[test]
fn all_31_pairs_render_and_verify() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), None);
    let (cfg, out) = (cfg.to_str().unwrap(), dir.path().join("data"));
    let out = out.to_str().unwrap();
    grasp_gen().ok([
        "render",
        "--config",
        cfg,
        "--out",
        out,
        "--workers",
        "2",
        "--no-progress",
    ]);
    let v = grasp_gen().ok(["dataset", "verify", out, "--config", cfg, "--decode"]);
    let text = &v.stdout;
    assert!(text.contains("31 pairs, 31 sequences"), "{text}");
    let prev = dir.path().join("preview");
    grasp_gen().ok(["preview", out, "--out", prev.to_str().unwrap()]);
    assert!(image::open(prev.join("contact_sheet.png")).is_ok());
    assert!(prev.join("preview.gif").metadata().unwrap().len() > 0);
}

#[test]
fn killed_then_resumed_equals_uninterrupted() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), Some("\"025_mug\""));
    let cfg = cfg.to_str().unwrap();
    let whole = dir.path().join("whole");
    let killed = dir.path().join("killed");
    grasp_gen().ok([
        "render",
        "--config",
        cfg,
        "--out",
        whole.to_str().unwrap(),
        "--no-progress",
    ]);

    let mut child = grasp_gen()
        .command([
            "render",
            "--config",
            cfg,
            "--out",
            killed.to_str().unwrap(),
            "--no-progress",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let manifest = killed.join("manifest.jsonl");
    while std::fs::read_to_string(&manifest)
        .map(|t| t.is_empty())
        .unwrap_or(true)
    {
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before the kill"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL: no cleanup at all
    child.wait().unwrap();

    grasp_gen().ok([
        "render",
        "--config",
        cfg,
        "--out",
        killed.to_str().unwrap(),
        "--resume",
        "--no-progress",
    ]);
    let (a, b) = (tree(&whole), tree(&killed));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs");
    }
    grasp_gen().ok([
        "dataset",
        "verify",
        killed.to_str().unwrap(),
        "--config",
        cfg,
    ]);
}
