//! `grasp-train eval` through the command line (issue 15, items 9 and 11):
//! without `--data` it evaluates the run's own test split whatever the
//! current directory, and in skip mode it records what it skipped.

use std::path::{Path, PathBuf};
use trainer::data::synthetic::{write_synthetic, Layout, SyntheticSpec};

use crate::lead_in;

fn grasp_train(cwd: &Path, args: &[&str]) -> (bool, String) {
    let out = grasp_test_support::Program::new(env!("CARGO_BIN_EXE_grasp-train"))
        .command(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// A tiny from-scratch model, as recipe overrides.
const TINY_RECIPE: [&str; 8] = [
    "--set",
    "mode=from-scratch",
    "--set",
    "width_mult=0.25",
    "--set",
    "input_size=32",
    "--set",
    "max_epochs=1",
];

/// Trains one tiny from-scratch seed on `work/data`, with relative paths
/// from `work` as a user would type them; returns the checkpoint.
fn train_tiny(work: &Path) -> PathBuf {
    write_synthetic(&work.join("data"), &SyntheticSpec::small(Layout::Generated)).unwrap();
    train_tiny_on_data(work, &[])
}

/// [`train_tiny`] on the data already in `work/data`, with `extra` train
/// flags.
fn train_tiny_on_data(work: &Path, extra: &[&str]) -> PathBuf {
    let mut args = vec!["--threads", "2", "train", "--data", "data", "--out", "run"];
    args.extend(TINY_RECIPE);
    args.extend(extra);
    let (ok, text) = grasp_train(work, &args);
    assert!(ok, "{text}");
    work.join("run/seed-0")
}

/// The dataset a report was made on, as an absolute path (a relative one is
/// relative to `cwd`, where eval ran).
fn report_dataset(cwd: &Path, report: &str) -> PathBuf {
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(cwd.join(report).join("report.json")).unwrap())
            .unwrap();
    cwd.join(json["dataset"].as_str().unwrap())
        .canonicalize()
        .unwrap()
}

#[test]
fn eval_without_data_reads_the_runs_dataset_from_any_directory() {
    let dir = tempfile::tempdir().unwrap();
    let (work, elsewhere) = (dir.path().join("work"), dir.path().join("elsewhere"));
    std::fs::create_dir_all(&work).unwrap();
    let ckpt = train_tiny(&work);
    // Another dataset at the same relative path, with the same sequence ids.
    let mut decoy = SyntheticSpec::small(Layout::Generated);
    decoy.seed = 99;
    write_synthetic(&elsewhere.join("data"), &decoy).unwrap();

    let ckpt_arg = ckpt.to_str().unwrap();
    let (ok, text) = grasp_train(&elsewhere, &["eval", "-c", ckpt_arg, "--out", "report"]);
    assert!(ok, "{text}");
    let used = report_dataset(&elsewhere, "report");
    assert_eq!(used, work.join("data").canonicalize().unwrap());

    // A run that recorded a relative path: resolved against the run folder.
    let meta_path = ckpt.join("best.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).unwrap()).unwrap();
    meta["train_config"]["data"] = "../data".into();
    std::fs::write(&meta_path, serde_json::to_vec(&meta).unwrap()).unwrap();
    let (ok, text) = grasp_train(&elsewhere, &["eval", "-c", ckpt_arg, "--out", "report2"]);
    assert!(ok, "{text}");
    let used = report_dataset(&elsewhere, "report2");
    assert_eq!(used, work.join("data").canonicalize().unwrap());

    // One that does not exist there is an error naming it, not a guess.
    meta["train_config"]["data"] = "data".into();
    std::fs::write(&meta_path, serde_json::to_vec(&meta).unwrap()).unwrap();
    let (ok, text) = grasp_train(&elsewhere, &["eval", "-c", ckpt_arg, "--out", "report3"]);
    assert!(!ok, "{text}");
    assert!(text.contains("relative to the run folder"), "{text}");
    assert!(text.contains("--data"), "{text}");
}

#[test]
fn eval_in_skip_mode_records_what_it_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path().join("work");
    std::fs::create_dir_all(&work).unwrap();
    let ckpt = train_tiny(&work);
    let test = dir.path().join("test");
    write_synthetic(&test, &SyntheticSpec::small(Layout::Generated)).unwrap();
    // An unreadable frame and a sequence without labels.
    let seqs = |p: &str| test.join(p);
    let frame = seqs("can/010_can/power_no3/Wrist_d435/rgb00000/00003.png");
    std::fs::write(&frame, b"not a png").unwrap();
    let json = seqs("plate/029_plate/pinch_no3/Wrist_d435/rgb00012/sequence.json");
    std::fs::remove_file(&json).unwrap();

    let (ok, text) = grasp_train(
        dir.path(),
        &[
            "eval",
            "-c",
            ckpt.to_str().unwrap(),
            "--data",
            test.to_str().unwrap(),
            "--out",
            "report",
        ],
    );
    assert!(ok, "{text}");
    let report = dir.path().join("report");
    let problems: Vec<serde_json::Value> =
        serde_json::from_slice(&std::fs::read(report.join("problems.json")).unwrap()).unwrap();
    let paths: Vec<&str> = problems
        .iter()
        .map(|p| p["path"].as_str().unwrap())
        .collect();
    assert_eq!(paths.len(), 2, "{problems:?}");
    assert!(paths.contains(&frame.to_str().unwrap()), "{paths:?}");
    assert!(paths.contains(&json.to_str().unwrap()), "{paths:?}");
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    assert!(md.contains("Bad data skipped: 2 problem(s)"), "{md}");
    assert!(md.contains("problems.json"), "{md}");
}

/// Renames every `Wrist_d435` folder under `root` to `Head_d435`: a dataset
/// seen only by the head camera.
fn as_head_camera(root: &Path) {
    for entry in walk_dirs(root) {
        if entry.file_name().is_some_and(|n| n == "Wrist_d435") {
            std::fs::rename(&entry, entry.with_file_name("Head_d435")).unwrap();
        }
    }
}

fn walk_dirs(root: &Path) -> Vec<PathBuf> {
    let mut dirs = vec![];
    for entry in std::fs::read_dir(root).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            dirs.extend(walk_dirs(&path));
            dirs.push(path);
        }
    }
    dirs
}

#[test]
fn eval_reads_the_camera_the_checkpoint_was_trained_on() {
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    write_synthetic(&work.join("data"), &SyntheticSpec::small(Layout::Generated)).unwrap();
    as_head_camera(&work.join("data"));
    train_tiny_on_data(work, &["--set", "reader.camera=Head_d435"]);
    // No --camera: the checkpoint's own camera, so the head frames are found.
    let (ok, text) = grasp_train(
        work,
        &["eval", "-c", "run/seed-0", "--data", "data", "--out", "r"],
    );
    assert!(ok, "{text}");
    // An explicit camera the dataset lacks is an error naming it.
    let args = [
        "eval",
        "-c",
        "run/seed-0",
        "--data",
        "data",
        "--camera",
        "Wrist_d435",
        "--out",
        "w",
    ];
    let (ok, text) = grasp_train(work, &args);
    assert!(!ok && text.contains("Wrist_d435"), "{text}");
}

#[test]
fn eval_trims_the_lead_in_before_inference_unless_told_to_keep_it() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = train_tiny(dir.path());
    let test = dir.path().join("test");
    write_synthetic(&test, &SyntheticSpec::small(Layout::Generated)).unwrap();
    lead_in::look_away_first(&lead_in::sequence_json(&test, "handle"), 4);
    let eval = |extra: &[&str], out: &str| {
        let mut args = vec!["eval", "-c", ckpt.to_str().unwrap(), "--data", "test"];
        args.extend(["--out", out]);
        args.extend(extra);
        let (ok, text) = grasp_train(dir.path(), &args);
        assert!(ok, "{text}");
        let json: serde_json::Value = serde_json::from_slice(
            &std::fs::read(dir.path().join(out).join("report.json")).unwrap(),
        )
        .unwrap();
        let md = std::fs::read_to_string(dir.path().join(out).join("report.md")).unwrap();
        (json, md)
    };
    let frames = |j: &serde_json::Value| j["runs"][0]["metrics"]["frames"].as_u64().unwrap();

    let (trimmed, md) = eval(&[], "trimmed");
    assert_eq!(trimmed["lead_in_trimmed"]["videos"], 1);
    assert_eq!(trimmed["lead_in_trimmed"]["frames"], 4);
    assert!(
        md.contains("Lead-in trimmed before inference: 4 frame(s) of 1 video(s)"),
        "{md}"
    );

    let (kept, md) = eval(&["--keep-lead-in"], "kept");
    assert!(kept.get("lead_in_trimmed").is_none());
    assert!(!md.contains("Lead-in"));
    assert_eq!(frames(&kept), frames(&trimmed) + 4);
}

#[test]
fn eval_pools_repeated_data_roots_into_one_report() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = train_tiny(dir.path());
    let ckpt = ckpt.to_str().unwrap();
    let mut other = SyntheticSpec::small(Layout::Generated);
    other.seed = 7;
    write_synthetic(&dir.path().join("draw-2"), &other).unwrap();
    let videos = |report: &str| {
        let json: serde_json::Value = serde_json::from_slice(
            &std::fs::read(dir.path().join(report).join("report.json")).unwrap(),
        )
        .unwrap();
        json["runs"][0]["metrics"]["videos"].as_u64().unwrap()
    };
    let one = ["eval", "-c", ckpt, "--data", "data", "--out", "one"];
    let (ok, text) = grasp_train(dir.path(), &one);
    assert!(ok, "{text}");
    let both = [
        "eval", "-c", ckpt, "--data", "data", "--data", "draw-2", "--out", "both",
    ];
    let (ok, text) = grasp_train(dir.path(), &both);
    assert!(ok, "{text}");
    assert_eq!(videos("both"), 2 * videos("one"));
    let md = std::fs::read_to_string(dir.path().join("both/report.md")).unwrap();
    assert!(md.contains("Pooled") && md.contains("draw-2"), "{md}");
    // videos.csv: one row per pooled video with its run's vote.
    let csv = std::fs::read_to_string(dir.path().join("both/videos.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "id,object,part,truth,vote_seed0,hand_seed0");
    assert_eq!(rows.len() as u64, 1 + videos("both"));
    assert!(rows.iter().any(|r| r.starts_with("draw-2/")), "{csv}");
    let names = ["power", "lateral", "pinch", "pinch3"];
    for r in &rows[1..] {
        let mut cells = r.rsplit(',');
        let hand = cells.next().unwrap();
        let vote = cells.next().unwrap();
        assert!(names.contains(&vote), "{r}");
        let commanded = hand.split(' ').next().unwrap();
        assert!(names.contains(&commanded) || commanded == "none", "{r}");
    }

    // An empty draw is named, not silently pooled.
    std::fs::create_dir_all(dir.path().join("empty")).unwrap();
    let empty = [
        "eval", "-c", ckpt, "--data", "data", "--data", "empty", "--out", "x",
    ];
    let (ok, text) = grasp_train(dir.path(), &empty);
    assert!(!ok && text.contains("empty"), "{text}");
}

/// The crop angle that half of a 32 px synthetic frame spans through the
/// synthetic lens (a focal length of 32 px).
fn half_frame_angle() -> String {
    grasp_schema::dataset::crop_angle_deg(0.5, 32.0, 32, 32).to_string()
}

/// The authors' layout has no sequence.json: a fixed-angle checkpoint
/// evaluates it once told the camera's lens, and the report records the
/// input record and the lens it used.
#[test]
fn eval_reads_the_authors_layout_with_a_fixed_angle_checkpoint_given_the_lens() {
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    write_synthetic(&work.join("data"), &SyntheticSpec::small(Layout::Generated)).unwrap();
    let angle = half_frame_angle();
    let crop = format!("reader.crop={{ angle_deg = {angle} }}");
    train_tiny_on_data(work, &["--set", &crop]);
    write_synthetic(&work.join("real"), &SyntheticSpec::small(Layout::Authors)).unwrap();
    let eval = |out: &str, lens: &[&str]| {
        let mut args = vec![
            "eval",
            "-c",
            "run/seed-0",
            "--data",
            "real",
            "--real-fps",
            "5",
        ];
        args.extend(["--out", out]);
        args.extend(lens);
        grasp_train(work, &args)
    };
    // Without a lens there is no angle to cut: refused, saying how to give one.
    let (ok, text) = eval("none", &[]);
    assert!(
        !ok && text.contains("--focal-px") && text.contains("rgb"),
        "{text}"
    );
    // A focal length in millimetres is not a camera.
    let (ok, text) = eval("mm", &["--focal-px", "1.93", "--lens-size", "224x224"]);
    assert!(
        !ok && text.contains("focal_px") && text.contains("field of view"),
        "{text}"
    );
    // The same lens measured at twice the resolution, and as a field of view.
    let hfov = (2.0 * (16.0f64 / 32.0).atan().to_degrees()).to_string();
    for (out, lens) in [
        ("focal", vec!["--focal-px", "64", "--lens-size", "64x64"]),
        ("hfov", vec!["--hfov-deg", hfov.as_str()]),
    ] {
        let (ok, text) = eval(out, &lens);
        assert!(ok, "{text}");
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(work.join(out).join("report.json")).unwrap())
                .unwrap();
        let input = &report["input"];
        assert_eq!(
            input["spec"]["crop"]["angle_deg"]
                .as_f64()
                .unwrap()
                .to_string(),
            angle,
            "{input}"
        );
        assert!(input["lens"].is_object(), "{input}");
        assert!(report["runs"][0]["metrics"]["videos"].as_u64().unwrap() > 0);
        let md = std::fs::read_to_string(work.join(out).join("report.md")).unwrap();
        assert!(
            md.contains("degrees") && md.contains("the checkpoint's"),
            "{md}"
        );
    }
}

/// Checkpoints trained on different inputs are not averaged as one model,
/// and a flag that replaces the checkpoint's crop is recorded.
#[test]
fn eval_refuses_a_mix_of_inputs_and_records_a_replaced_crop() {
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    write_synthetic(&work.join("data"), &SyntheticSpec::small(Layout::Generated)).unwrap();
    train_tiny_on_data(work, &[]);
    let mut args = vec![
        "--threads",
        "2",
        "train",
        "--data",
        "data",
        "--out",
        "cropped",
    ];
    args.extend(TINY_RECIPE);
    args.extend(["--set", "reader.crop={ fraction = 0.5 }"]);
    let (ok, text) = grasp_train(work, &args);
    assert!(ok, "{text}");
    let args = [
        "eval",
        "-c",
        "run/seed-0",
        "-c",
        "cropped/seed-0",
        "--data",
        "data",
    ];
    let (ok, text) = grasp_train(work, &args);
    assert!(!ok, "{text}");
    assert!(
        text.contains("run/seed-0") && text.contains("cropped/seed-0") && text.contains("0.5"),
        "{text}"
    );
    let args = [
        "eval",
        "-c",
        "run/seed-0",
        "--data",
        "data",
        "--center-crop",
        "0.5",
    ];
    let (ok, text) = grasp_train(work, &[&args[..], &["--out", "r"]].concat());
    assert!(ok, "{text}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(work.join("r/report.json")).unwrap()).unwrap();
    let overrides = report["input"]["overrides"].to_string();
    assert!(
        overrides.contains("--center-crop 0.5") && overrides.contains("whole frame"),
        "{overrides}"
    );

    // 1 x 1 frames give the backbone nothing to see: an error naming a
    // frame, not "100 % per video".
    let tiny = SyntheticSpec {
        size: 1,
        ..SyntheticSpec::small(Layout::Generated)
    };
    write_synthetic(&work.join("dots"), &tiny).unwrap();
    let args = ["eval", "-c", "run/seed-0", "--data", "dots", "--out", "d"];
    let (ok, text) = grasp_train(work, &args);
    assert!(
        !ok && text.contains("1x1") && text.contains("16 px minimum"),
        "{text}"
    );
    assert!(text.contains("dots/can/010_can"), "{text}");
}

/// `eval` writes report.html: one file that needs nothing beside it, with
/// every video's strip and each seed's per-frame answers. Opened in
/// headless Chromium (`GRASP_REQUIRE_BROWSER=1` makes a missing browser a
/// failure), its script runs without an error, a known video's strip is
/// in the DOM and the screenshot is not blank; `summarize` writes
/// index.html linking to it.
#[test]
fn eval_writes_a_report_page_that_renders_in_a_browser() {
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    write_synthetic(&work.join("data"), &SyntheticSpec::small(Layout::Generated)).unwrap();
    let crop = ["--set", "reader.crop={ fraction = 0.5 }", "--seeds", "2"];
    train_tiny_on_data(work, &crop);
    let args = [
        "eval",
        "-c",
        "run/seed-0",
        "-c",
        "run/seed-1",
        "--data",
        "data",
        "--out",
        "report",
    ];
    let (ok, text) = grasp_train(work, &args);
    assert!(ok, "{text}");
    let page = work.join("report/report.html");
    let html = std::fs::read_to_string(&page).unwrap();
    // Self-contained: no outside address, pictures inline.
    assert!(
        !html.contains("http://") && !html.contains("https://"),
        "report.html names an outside URL"
    );
    assert!(html.contains("src=\"data:image/jpeg;base64,"));
    // A known video, from videos.csv: its strip and a mark row per seed.
    let csv = std::fs::read_to_string(work.join("report/videos.csv")).unwrap();
    let known = csv.lines().nth(1).unwrap().split(',').next().unwrap();
    let article = format!("data-id=\"{known}\"");
    let at = html.find(&article).expect("the known video's article");
    let own = &html[at..at + html[at..].find("</article>").unwrap()];
    assert!(own.contains("<img class=\"frames\""), "{own}");
    for seed in ["seed 0", "seed 1"] {
        assert!(own.contains(seed), "{seed} missing: {own}");
    }
    let videos = csv.lines().count() - 1;
    assert_eq!(html.matches("<article class=\"video\"").count(), videos);
    // The summary's page links to it.
    std::fs::write(
        work.join("timing.json"),
        "{\"render\": 12, \"total_after_setup\": 40}",
    )
    .unwrap();
    let args = [
        "summarize",
        "--report",
        "tiny:report",
        "--out",
        "summary",
        "--timing",
        "timing.json",
        "--preview",
        "no-such-sheet.png",
    ];
    let (ok, text) = grasp_train(work, &args);
    assert!(ok, "{text}");
    let index = std::fs::read_to_string(work.join("summary/index.html")).unwrap();
    assert!(index.contains("href=\"../report/report.html\""), "{index}");
    assert!(index.contains("total_after_setup") && index.contains("no-such-sheet.png"));

    let test = "eval_writes_a_report_page_that_renders_in_a_browser";
    let Some(browser) = grasp_test_support::prerequisite::require_browser(test) else {
        return;
    };
    use grasp_test_support::browser;
    for p in [&page, &work.join("summary/index.html")] {
        let r = browser::dump_dom(&browser, p);
        assert!(
            r.dom.contains("data-script=\"ok\"") && !r.dom.contains("<pre id=\"script-error\""),
            "the page's script did not run cleanly in {}:\n{}\n{}",
            p.display(),
            r.dom
                .lines()
                .filter(|l| l.contains("script"))
                .collect::<Vec<_>>()
                .join("\n"),
            r.log
        );
        assert!(r.script_errors().is_empty(), "{:?}", r.script_errors());
    }
    let r = browser::dump_dom(&browser, &page);
    assert!(
        r.dom.contains(&article),
        "the known video is not in the DOM"
    );
    let count = format!("{videos} of {videos} videos shown");
    assert!(
        r.dom.contains(&count),
        "the filters did not count the videos"
    );
    // The outcome filter, preset from the address, keeps the wrong votes.
    let wrong = csv
        .lines()
        .skip(1)
        .filter(|row| {
            let f: Vec<&str> = row.split(',').collect();
            f[4..].iter().any(|vote| *vote != f[3])
        })
        .count();
    let r = browser::dump_dom_at(&browser, &page, "outcome=vote-wrong");
    let count = format!("{wrong} of {videos} videos shown");
    assert!(r.dom.contains(&count), "expected {count}");
    assert_eq!(r.dom.matches(" hidden=\"\"").count(), videos - wrong);
    let r = browser::dump_dom_at(&browser, &page, "outcome=vote-right");
    let count = format!("{} of {videos} videos shown", videos - wrong);
    assert!(r.dom.contains(&count), "expected {count}");
    assert_eq!(r.dom.matches(" hidden=\"\"").count(), wrong);
    let png = work.join("report.png");
    browser::screenshot(&browser, &page, &png, 1200, 1600);
    let shot = image::open(&png).unwrap().to_luma8();
    let n = f64::from(shot.width() * shot.height());
    let mean = shot.pixels().map(|p| f64::from(p.0[0])).sum::<f64>() / n;
    let var = shot
        .pixels()
        .map(|p| (f64::from(p.0[0]) - mean).powi(2))
        .sum::<f64>()
        / n;
    assert!(
        var > 100.0,
        "the screenshot looks blank (luma variance {var:.1})"
    );
}

/// A stand-in FC checkpoint (random MobileNetV2 backbone, 32 px) and an
/// LSTM head trained on the same data and backbone: (data, fc, lstm).
fn fc_and_lstm(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    use grasp_model::backbone::Architecture;
    let (set, fc) = trainer::stand_in::stand_in_run(dir, 32, Architecture::MobileNetV2).unwrap();
    let mut cfg = trainer::config::TrainConfig {
        head: grasp_model::heads::HeadKind::Lstm,
        max_epochs: 1,
        lstm_hidden: 8,
        ..set.config("run-lstm")
    };
    cfg.split.val_fraction = 0.34;
    cfg.split.test_fraction = 0.0;
    let lstm = trainer::experiment::run(&cfg, 1).unwrap().runs[0]
        .checkpoint
        .clone();
    (dir.join("data"), fc, lstm)
}

fn program() -> grasp_test_support::Program {
    grasp_test_support::Program::new(env!("CARGO_BIN_EXE_grasp-train"))
}

/// `eval -c C1 -c C2 ... --data DATA --out OUT`.
fn eval_args(checkpoints: &[&Path], data: &Path, out: &Path) -> Vec<std::ffi::OsString> {
    let mut args: Vec<std::ffi::OsString> = vec!["eval".into()];
    for c in checkpoints {
        args.push("-c".into());
        args.push(c.into());
    }
    args.extend(["--data".into(), data.into(), "--out".into(), out.into()]);
    args
}

/// A copy of checkpoint folder `ckpt` at `to`, its best.json changed by
/// `edit`.
fn edited_copy(ckpt: &Path, to: &Path, edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(ckpt).unwrap().flatten() {
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
    let best = to.join("best.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&best).unwrap()).unwrap();
    edit(&mut meta);
    std::fs::write(&best, meta.to_string()).unwrap();
    to.to_path_buf()
}

#[test]
fn eval_refuses_mixed_heads_duplicates_other_class_lists_and_broken_outputs() {
    // Issue 60, cases 9, 12 and 13: each gave a normal report, exit 0.
    let dir = tempfile::tempdir().unwrap();
    let (data, fc, lstm) = fc_and_lstm(dir.path());
    let out = dir.path().join("report");
    let done = program().run(eval_args(&[&fc, &lstm], &data, &out));
    let line = done.assert_user_error();
    assert!(
        line.contains("different heads") && line.contains("lstm"),
        "{line}"
    );
    let line = program().user_error(eval_args(&[&fc, &fc], &data, &out));
    assert!(line.contains("given twice"), "{line}");
    // The same checkpoint by another path is the same checkpoint.
    let other_path = fc.parent().unwrap().join("../run/seed-0");
    let line = program().user_error(eval_args(&[&fc, &other_path], &data, &out));
    assert!(line.contains("given twice"), "{line}");
    for (name, classes) in [
        (
            "swapped",
            serde_json::json!(["lateral", "power", "pinch", "pinch3", "no_grasp"]),
        ),
        (
            "twice",
            serde_json::json!(["power", "power", "pinch", "pinch3", "no_grasp"]),
        ),
    ] {
        let copy = edited_copy(&fc, &dir.path().join(name), |m| m["classes"] = classes);
        let line = program().user_error(eval_args(&[&copy], &data, &out));
        assert!(line.contains("classes"), "{name}: {line}");
    }
    // Finite weights whose outputs are NaN.
    let broken = edited_copy(&fc, &dir.path().join("broken"), |_| {});
    let weights = broken.join("best.safetensors");
    let tensors = candle_core::safetensors::load(&weights, &candle_core::Device::Cpu).unwrap();
    let huge: std::collections::HashMap<String, candle_core::Tensor> = tensors
        .into_iter()
        .map(|(k, t)| {
            let t = match k.starts_with("head.") {
                true => (t.ones_like().unwrap() * 3e38).unwrap(),
                false => t,
            };
            (k, t)
        })
        .collect();
    candle_core::safetensors::save(&huge, &weights).unwrap();
    let line = program().user_error(eval_args(&[&broken], &data, &out));
    assert!(line.contains("invalid model output"), "{line}");
    assert!(!out.join("report.json").exists(), "a report was written");
    // Case 8: a frame rate of 0 (or NaN) for data without sequence.json
    // panicked; refused before any data is read.
    for fps in ["0", "nan"] {
        let missing = dir.path().join("no-data-here");
        let mut args = eval_args(&[&fc], &missing, &out);
        args.extend([
            "--hfov-deg".into(),
            "45".into(),
            "--real-fps".into(),
            fps.into(),
        ]);
        let line = program().user_error(args);
        assert!(
            line.contains("real_fps") && !line.contains("no-data-here"),
            "{line}"
        );
    }
    // The checkpoint itself is fine.
    let done = program().run(eval_args(&[&fc], &data, &out));
    assert!(done.status.success(), "{}", done.stderr);
}

#[test]
fn eval_says_which_folder_the_manifest_lists_but_is_missing() {
    // Issue 60, case 14: 7 of 8 sequences were scored without a word.
    let dir = tempfile::tempdir().unwrap();
    let ckpt = trainer::stand_in::stand_in_checkpoint(
        dir.path(),
        32,
        grasp_model::backbone::Architecture::MobileNetV2,
    )
    .unwrap();
    let data = dir.path().join("data");
    let manifest = std::fs::read_to_string(data.join("manifest.jsonl")).unwrap();
    let first: serde_json::Value = serde_json::from_str(manifest.lines().next().unwrap()).unwrap();
    let gone = first["path"].as_str().unwrap().to_string();
    std::fs::remove_dir_all(data.join(&gone)).unwrap();
    let out = dir.path().join("report");
    // Skipping bad data (eval's default), it says so, scores the rest and
    // lists the folder beside the report.
    let done = program().run(eval_args(&[&ckpt], &data, &out));
    assert!(done.status.success(), "{}", done.stderr);
    assert!(
        done.stderr.contains(&gone) && done.stderr.contains("listed in manifest.jsonl but missing"),
        "{}",
        done.stderr
    );
    let problems = std::fs::read_to_string(out.join("problems.json")).unwrap();
    assert!(problems.contains(&gone), "{problems}");
    // Told to fail on bad data, it refuses, naming the folder.
    let mut args = eval_args(&[&ckpt], &data, &dir.path().join("strict"));
    args.extend(["--on-bad-data".into(), "fail".into()]);
    let line = program().user_error(args);
    assert!(line.contains(&gone) && line.contains("missing"), "{line}");
}

#[test]
fn train_into_a_folder_holding_a_checkpoint_is_refused_unless_overwritten() {
    // Issue 60, case 14: the checkpoint was overwritten without a word.
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    let ckpt = train_tiny(work);
    let before = std::fs::read(ckpt.join("best.safetensors")).unwrap();
    let mut args: Vec<&str> = vec!["--threads", "2", "train", "--data", "data", "--out", "run"];
    args.extend(TINY_RECIPE);
    args.extend(["--set", "seed=0"]);
    let (ok, text) = grasp_train(work, &args);
    assert!(!ok, "{text}");
    assert!(
        text.contains("already holds a checkpoint") && text.contains("--overwrite"),
        "{text}"
    );
    assert_eq!(
        std::fs::read(ckpt.join("best.safetensors")).unwrap(),
        before
    );
    args.push("--overwrite");
    let (ok, text) = grasp_train(work, &args);
    assert!(ok, "{text}");
}
