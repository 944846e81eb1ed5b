//! Conventions shared by every program (grasp_main,
//! grasp_test_support::program): a closed stdout ends `grasp-train` quietly,
//! a user error prints its message, not a backtrace, even under
//! `RUST_BACKTRACE=1`, and logs into a pipe carry no colour codes.

use grasp_test_support::program::{assert_no_colour_codes, Program};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use trainer::eval::metrics::Metrics;
use trainer::eval::report::RunReport;
use trainer::eval::Report;

fn grasp_train() -> Program {
    Program::new(env!("CARGO_BIN_EXE_grasp-train"))
}

/// `summarize --out DIR/summary --report fc:REPORT`.
fn summarize(dir: &Path, report: &Path) -> Vec<OsString> {
    let summary = dir.join("summary");
    let report = format!("fc:{}", report.display());
    [
        "summarize".into(),
        "--out".into(),
        summary.into_os_string(),
        "--report".into(),
        report.into(),
    ]
    .to_vec()
}

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
    grasp_train().assert_quiet_in_closed_pipe(summarize(dir.path(), &report));
    assert!(
        dir.path().join("summary/summary.md").is_file(),
        "the work before the print is done"
    );
}

#[test]
fn a_user_error_prints_its_message_without_a_backtrace() {
    let dir = tempfile::tempdir().unwrap();
    let line = grasp_train().user_error(summarize(dir.path(), &dir.path().join("missing-report")));
    assert!(line.contains("missing-report"), "{line}");
}

#[test]
fn stand_in_logs_without_colour_codes_into_a_pipe_and_prints_its_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("stand-in");
    let done = grasp_train().run([
        "stand-in".as_ref(),
        "--backbone".as_ref(),
        "mobilenet-v2".as_ref(),
        "--size".as_ref(),
        "32".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(done.status.success(), "{}", done.stderr);
    assert!(done.stderr.contains("INFO"), "{}", done.stderr);
    assert_no_colour_codes(&done.stderr);
    let checkpoint = Path::new(done.stdout.trim());
    assert!(checkpoint.join("best.json").is_file(), "{}", done.stdout);
    assert!(
        checkpoint.join("best.safetensors").is_file(),
        "{}",
        done.stdout
    );
}

/// `grasp-train train` with `--set KEY=VALUE` on data that does not exist:
/// the setting must be refused first, naming its field, as a user error.
fn refused_setting(set: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-data-here");
    let out = dir.path().join("run");
    let line = grasp_train().user_error([
        "train".as_ref(),
        "--recipe".as_ref(),
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../configs/recipes/fc.toml")
            .as_os_str(),
        "--data".as_ref(),
        missing.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--set".as_ref(),
        set.as_ref(),
    ]);
    assert!(
        !line.contains("no-data-here"),
        "{set}: data read first: {line}"
    );
    assert!(!out.exists(), "{set}: {} written", out.display());
    line
}

#[test]
fn numeric_training_settings_are_refused_naming_the_field_before_any_data() {
    // Issue 60, cases 6, 10 and 11.
    for (set, field) in [
        ("input_size=100000", "input_size"),
        ("optimizer.lr=-1", "optimizer.lr"),
        ("optimizer.lr=0", "optimizer.lr"),
        ("optimizer.lr=nan", "optimizer.lr"),
        ("batch_size=0", "batch_size"),
        ("max_epochs=0", "max_epochs"),
        ("split.val_fraction=1.5", "split.val_fraction"),
        ("split.test_fraction=nan", "split.test_fraction"),
        ("reader.real_fps=nan", "reader.real_fps"),
        ("reader.real_fps=0", "reader.real_fps"),
    ] {
        let line = refused_setting(set);
        assert!(line.contains(field), "{set}: {line}");
    }
}

#[test]
fn the_help_names_the_default_backbone() {
    // Issue 60, case 15: it opened with "MobileNetV2 in candle".
    let done = grasp_train().run(["--help"]);
    assert!(done.status.success(), "{}", done.stderr);
    let first = done.stdout.lines().next().unwrap_or_default();
    assert!(first.contains("EfficientNet-Lite0"), "{first}");
    assert!(
        !done.stdout.contains("MobileNetV2 in candle"),
        "{}",
        done.stdout
    );
}

#[test]
fn the_docs_name_no_crop_flag_that_no_program_accepts() {
    // Issue 60, case 15: the fixed-angle crop is `reader.crop`, not a flag.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = vec![root.join("README.md")];
    for e in std::fs::read_dir(root.join("docs")).unwrap().flatten() {
        files.extend((e.path().extension() == Some("md".as_ref())).then(|| e.path()));
    }
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        assert!(!text.contains("--crop-angle-deg"), "{}", f.display());
    }
}
