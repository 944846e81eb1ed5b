//! The output folder's lock (issue 15, item 6): a second render into a
//! folder in use is refused naming the holder; a killed run's lock is
//! recognised as stale and removed; a holder on another machine needs
//! `--break-lock`, which never overrides a live one; shards that split the
//! work share a folder, and a run overlapping one of them is refused.

use crate::render_common::{grasp_gen, have_blender, tree};
use generator::dataset::lock::{self, Holder};
use generator::render::Shard;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

fn config(dir: &Path, sequences_per_pair: u32) -> PathBuf {
    let text = format!(
        "[dataset]\nsequences_per_pair = {sequences_per_pair}\nconditions = [\"default\"]\n\
         objects = [\"025_mug\"]\n\n[plan.camera]\nresolution = [32, 32]\n\n\
         [plan.trajectory]\nfps = 1.0\n\n[render]\nengine = \"workbench\"\nsamples = 1\n"
    );
    let path = dir.join("tiny.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn render_cmd(cfg: &Path, out: &Path, extra: &[&str]) -> Command {
    let mut c = grasp_gen().command(["render", "--config"]);
    c.arg(cfg)
        .arg("--out")
        .arg(out)
        .arg("--no-progress")
        .args(extra);
    c
}

fn run(mut c: Command) -> (bool, String) {
    let out: Output = c.output().unwrap();
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .unwrap()
        .trim()
        .to_string()
}

fn lock_file(out: &Path, shard: &str) -> PathBuf {
    out.join(".grasp-gen/locks")
        .join(format!("shard-{}.lock", shard.replace('/', "-of-")))
}

#[test]
fn a_render_into_a_folder_in_use_is_refused_naming_the_holder() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), 1);
    let out = dir.path().join("data");
    let held = lock::acquire(&out.join(".grasp-gen"), Shard::ALL, "render", false).unwrap();

    for extra in [&[][..], &["--resume", "--break-lock"][..]] {
        let (ok, text) = run(render_cmd(&cfg, &out, extra));
        assert!(!ok, "a second render ran:\n{text}");
        for needle in [
            format!("pid {}", std::process::id()),
            format!("on host {}", hostname()),
            "started ".to_string(),
            "command: ".to_string(),
            "is running".to_string(),
        ] {
            assert!(text.contains(&needle), "'{needle}' missing:\n{text}");
        }
    }
    // Nothing was touched: no partial sequence, no worker log.
    assert!(!out.join(".grasp-gen/logs").exists());
    drop(held);
    let (ok, text) = run(render_cmd(&cfg, &out, &[]));
    assert!(ok, "{text}");
    assert!(
        !lock_file(&out, "0/1").exists(),
        "the lock outlived its run"
    );
}

#[test]
fn a_killed_render_leaves_a_stale_lock_that_the_next_run_removes() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), 1);
    let out = dir.path().join("data");
    let mut child = render_cmd(&cfg, &out, &[])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let manifest = out.join("manifest.jsonl");
    while std::fs::read_to_string(&manifest)
        .map(|t| t.is_empty())
        .unwrap_or(true)
    {
        assert!(child.try_wait().unwrap().is_none(), "finished too soon");
        std::thread::sleep(Duration::from_millis(20));
    }
    let pid = child.id();
    child.kill().unwrap(); // SIGKILL: the lock stays behind
    child.wait().unwrap();
    assert!(lock_file(&out, "0/1").exists());

    let (ok, text) = run(render_cmd(&cfg, &out, &["--resume"]));
    assert!(ok, "{text}");
    assert!(text.contains("removing the stale lock"), "{text}");
    assert!(
        text.contains(&format!("no process {pid} on this machine")),
        "{text}"
    );
    assert!(!lock_file(&out, "0/1").exists());
}

/// A lock as written by a run on another machine.
fn foreign_lock(out: &Path) -> PathBuf {
    let path = lock_file(out, "0/1");
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let holder = Holder {
        pid: 4242,
        host: "far-away-node".into(),
        boot_id: "another-boot".into(),
        pid_namespace: "pid:[1]".into(),
        process_start: Some(1),
        started_unix: 1_700_000_000,
        command: "grasp-gen render --out data".into(),
        purpose: "render".into(),
        shard: "0/1".into(),
        token: "foreign".into(),
        slurm_job_id: None,
        slurm_restart_count: None,
    };
    std::fs::write(&path, serde_json::to_vec(&holder).unwrap()).unwrap();
    path
}

#[test]
fn a_holder_on_another_machine_needs_break_lock_which_spares_a_live_one() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), 1);
    let out = dir.path().join("data");
    let path = foreign_lock(&out);
    let fast = |extra: &[&str]| {
        let mut c = render_cmd(&cfg, &out, extra);
        c.env(lock::HEARTBEAT_ENV, "100");
        run(c)
    };

    let (ok, text) = fast(&[]);
    assert!(!ok, "{text}");
    assert!(text.contains("pid 4242 on host far-away-node"), "{text}");
    assert!(text.contains("--break-lock"), "{text}");

    // A heartbeat that moves: --break-lock refuses.
    let beating = Arc::new(AtomicBool::new(true));
    let (b, p) = (beating.clone(), path.clone());
    let heart = std::thread::spawn(move || {
        while b.load(Ordering::SeqCst) {
            let f = std::fs::OpenOptions::new().write(true).open(&p).unwrap();
            f.set_modified(SystemTime::now()).unwrap();
            std::thread::sleep(Duration::from_millis(20));
        }
    });
    let (ok, text) = fast(&["--break-lock"]);
    beating.store(false, Ordering::SeqCst);
    heart.join().unwrap();
    assert!(!ok, "a live holder was overridden:\n{text}");
    assert!(text.contains("heartbeat is still moving"), "{text}");

    // A silent one: --break-lock takes over after three heartbeats.
    let (ok, text) = fast(&["--break-lock"]);
    assert!(ok, "{text}");
    assert!(text.contains("no heartbeat"), "{text}");
    assert!(!path.exists());
}

#[test]
fn disjoint_shards_share_a_folder_and_an_overlapping_run_is_refused() {
    if !have_blender() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), 2);
    let (shared, whole) = (dir.path().join("shared"), dir.path().join("whole"));

    // While shard 0/2 is held, a whole run is refused and names it.
    let held = lock::acquire(
        &shared.join(".grasp-gen"),
        Shard { index: 0, count: 2 },
        "render",
        false,
    )
    .unwrap();
    let (ok, text) = run(render_cmd(&cfg, &shared, &[]));
    assert!(!ok, "{text}");
    assert!(text.contains("render of shard 0/2"), "{text}");
    drop(held);

    // Both shards at once into the same folder.
    let children: Vec<_> = ["0/2", "1/2"]
        .iter()
        .map(|s| {
            render_cmd(&cfg, &shared, &["--shard", s])
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in children {
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let (ok, text) = run(render_cmd(&cfg, &whole, &[]));
    assert!(ok, "{text}");
    let (a, b) = (tree(&whole), tree(&shared));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs");
    }
    let v = grasp_gen()
        .command(["dataset", "verify"])
        .arg(&shared)
        .arg("--config")
        .arg(&cfg)
        .output()
        .unwrap();
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stdout));
}
