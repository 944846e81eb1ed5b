//! Conventions shared by every program (grasp_support::cli): a closed stdout
//! ends `grasp-train` quietly, and a user error prints its message, not a
//! backtrace, even under `RUST_BACKTRACE=1`.

use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use trainer::eval::metrics::Metrics;
use trainer::eval::report::RunReport;
use trainer::eval::Report;

const BIN: &str = env!("CARGO_BIN_EXE_grasp-train");

fn write_report(dir: &Path) -> PathBuf {
    let runs = vec![RunReport {
        checkpoint: PathBuf::from("run/seed-0"),
        seed: 0,
        metrics: Metrics {
            videos: 4,
            video_accuracy: 0.75,
            frame_accuracy: 0.7,
            ..Default::default()
        },
        videos: Vec::new(),
    }];
    let r = Report::new("frozen-pretrained", "fc", Path::new("data/test"), runs);
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(
        dir.join("report.json"),
        serde_json::to_string_pretty(&r).unwrap(),
    )
    .unwrap();
    dir.to_path_buf()
}

#[test]
fn printing_into_a_closed_pipe_ends_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let report = write_report(&dir.path().join("report"));
    // `grasp-train summarize ... | head -0`: the reader is gone before the
    // first line is printed.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = Command::new(BIN)
        .args(["summarize", "--out"])
        .arg(dir.path().join("summary"))
        .arg("--report")
        .arg(format!("fc:{}", report.display()))
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
    assert!(
        dir.path().join("summary/summary.md").is_file(),
        "the work before the print is done"
    );
}

#[test]
fn a_user_error_prints_its_message_without_a_backtrace() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(BIN)
        .args(["summarize", "--out"])
        .arg(dir.path().join("summary"))
        .arg("--report")
        .arg(format!(
            "fc:{}",
            dir.path().join("missing-report").display()
        ))
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.to_lowercase().contains("backtrace"), "{stderr}");
    let last = stderr.lines().last().unwrap_or_default();
    assert!(
        last.starts_with("Error: ") && last.contains("missing-report"),
        "{stderr}"
    );
}

#[test]
fn stand_in_logs_without_colour_codes_into_a_pipe_and_prints_its_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(BIN)
        .args([
            "stand-in",
            "--backbone",
            "mobilenet-v2",
            "--size",
            "32",
            "--out",
        ])
        .arg(dir.path().join("stand-in"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("INFO"), "{stderr}");
    assert!(
        !stderr.contains('\x1b'),
        "ANSI escape codes in a pipe: {stderr:?}"
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let checkpoint = Path::new(stdout.trim());
    assert!(checkpoint.join("best.json").is_file(), "{stdout}");
    assert!(checkpoint.join("best.safetensors").is_file(), "{stdout}");
}
