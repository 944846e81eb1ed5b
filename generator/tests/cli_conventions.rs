//! Conventions shared by every program (grasp_support::cli): a closed stdout
//! ends `grasp-gen` quietly, and a user error prints its message, not a
//! backtrace, even under `RUST_BACKTRACE=1`.

use std::os::unix::process::ExitStatusExt;
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_grasp-gen");

#[test]
fn printing_into_a_closed_pipe_ends_quietly() {
    // `grasp-gen objects list | head -0`: the reader is gone before the
    // first line is printed.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = Command::new(BIN)
        .args(["objects", "list"])
        .env("RUST_BACKTRACE", "1")
        .stdin(Stdio::null())
        .stdout(writer)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        out.status.signal(),
        Some(13),
        "SIGPIPE: {:?} {stderr}",
        out.status
    );
}

#[test]
fn a_user_error_prints_its_message_without_a_backtrace() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.toml");
    let out = Command::new(BIN)
        .args(["plan", "--config"])
        .arg(&missing)
        .arg("--out")
        .arg(dir.path().join("plans.jsonl"))
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.to_lowercase().contains("backtrace"), "{stderr}");
    let last = stderr.lines().last().unwrap_or_default();
    assert!(
        last.starts_with("Error: ") && last.contains("missing.toml"),
        "{stderr}"
    );
}
