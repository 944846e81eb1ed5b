//! Faults during a render are reported as what they are (issue 15, item 8):
//! a full disk as the operating system's "No space left on device", which
//! stops the run instead of failing or retrying every sequence; retries are
//! logged even without a terminal or with `--no-progress`.

use crate::render_common::{exe, grasp_gen, have_blender};
use std::path::{Path, PathBuf};
use std::process::Command;

fn config(dir: &Path) -> PathBuf {
    let text = "[dataset]\nsequences_per_pair = 1\nconditions = [\"default\"]\n\
                objects = [\"025_mug\"]\n\n[plan.camera]\nresolution = [32, 32]\n\n\
                [plan.trajectory]\nfps = 1.0\n\n[render]\nengine = \"workbench\"\nsamples = 1\n";
    let path = dir.join("tiny.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs `script` (sh) in a private mount namespace, so the tmpfs it mounts
/// vanishes with it: `unshare -m` as root, else in a user namespace.
fn in_mount_namespace(script: &str, args: &[&Path]) -> std::process::Output {
    let mut tried = Vec::new();
    for flags in [&["-m"][..], &["-r", "-m"][..]] {
        let out = Command::new("unshare")
            .args(flags)
            .args(["sh", "-c", script, "sh"])
            .args(args)
            .env("RUST_BACKTRACE", "0")
            .output();
        match out {
            Ok(o) if !String::from_utf8_lossy(&o.stderr).contains("unshare failed") => return o,
            Ok(o) => tried.push(String::from_utf8_lossy(&o.stderr).into_owned()),
            Err(e) => tried.push(e.to_string()),
        }
    }
    panic!(
        "this test mounts a tiny tmpfs to fill it and needs `unshare -m` (root) or \
         unprivileged user namespaces: {tried:?}"
    );
}

#[test]
fn a_full_disk_is_reported_as_no_space_left_and_stops_the_run() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path());
    let mnt = dir.path().join("mnt");
    std::fs::create_dir_all(&mnt).unwrap();
    // 96 KiB: the mesh cache (about 60 KiB) fits, the frames do not all.
    let script = "mount -t tmpfs -o size=96k tmpfs \"$2\" || exit 99
        \"$3\" render --config \"$1\" --out \"$2/data\" --no-progress
        echo \"render-exit=$?\"
        \"$3\" dataset verify \"$2/data\" --config \"$1\"
        exit 0";
    let out = in_mount_namespace(script, &[&cfg, &mnt, &exe()]);
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    assert!(text.contains("render-exit=1"), "{text}");
    assert!(text.contains("No space left on device"), "{text}");
    assert!(text.contains("--resume"), "{text}");
    assert!(!text.contains("missing or empty"), "{text}");
    assert!(
        !text.contains("retrying"),
        "a full disk was retried:\n{text}"
    );
    // Whatever finished is whole: verify finds missing sequences only.
    let problems: Vec<&str> = text.lines().filter(|l| l.starts_with("PROBLEM")).collect();
    assert!(!problems.is_empty(), "{text}");
    assert!(
        problems.iter().all(|p| p.contains("missing")),
        "damaged files were kept:\n{text}"
    );
}

#[test]
fn retries_are_logged_without_a_terminal() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path());
    let marker = dir.path().join("crash-marker");
    // stderr is a pipe here, and --no-progress on top.
    let out = grasp_gen()
        .command(["render", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(dir.path().join("data"))
        .arg("--no-progress")
        .env(generator::render::worker::CRASH_ONCE_ENV, &marker)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(marker.exists(), "the worker never crashed");
    assert!(stderr.contains("retrying 025_mug/"), "{stderr}");
    assert!(stderr.contains("worker process died"), "{stderr}");
}
