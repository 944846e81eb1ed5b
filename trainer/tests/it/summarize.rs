//! `grasp-train summarize` on hand-made report.json files whose numbers are
//! worked out by hand below.

use std::path::{Path, PathBuf};
use trainer::eval::metrics::{Baseline, HandMetrics, Metrics};
use trainer::eval::report::RunReport;
use trainer::eval::summary::{Entry, Summary, SummarySpec};
use trainer::eval::Report;

/// A report of one run per `(video, frame)` accuracy pair; the baseline is
/// 0.75 in every run, single-grasp videos 1.0, multi-grasp videos 0.2 below
/// all videos.
fn write_report(dir: &Path, runs: &[(f64, f64)]) -> PathBuf {
    let runs: Vec<_> = runs.iter().map(|&(v, f)| (v, f, v)).collect();
    write_report_with_hand(dir, &runs)
}

/// [`write_report`] with the hand's decision's accuracy of each run given
/// (the third value).
fn write_report_with_hand(dir: &Path, runs: &[(f64, f64, f64)]) -> PathBuf {
    let runs = runs
        .iter()
        .enumerate()
        .map(|(seed, (video, frame, hand))| RunReport {
            checkpoint: PathBuf::from(format!("run/seed-{seed}")),
            seed: seed as u64,
            metrics: Metrics {
                videos: 10,
                video_accuracy: *video,
                video_accuracy_single: Some(1.0),
                video_accuracy_multi: Some(video - 0.2),
                frame_accuracy: *frame,
                frame_accuracy_without_no_grasp: frame - 0.1,
                baseline: Baseline {
                    video_accuracy: 0.75,
                    ..Default::default()
                },
                hand: HandMetrics {
                    accuracy: *hand,
                    ..Default::default()
                },
                ..Default::default()
            },
            videos: Vec::new(),
        })
        .collect();
    let mut r = Report::new("frozen-pretrained", "fc", Path::new("data/test"), runs);
    r.backbone = "frozen backbone from runs/scratch/seed-0".into();
    r.train_sequences = Some(62);
    r.sequences_per_pair = Some(2);
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(
        dir.join("report.json"),
        serde_json::to_string_pretty(&r).unwrap(),
    )
    .unwrap();
    dir.to_path_buf()
}

fn entry(label: &str, x: Option<f64>, path: &Path) -> Entry {
    Entry {
        label: label.into(),
        x,
        path: path.to_path_buf(),
    }
}

#[test]
fn table_and_plot_of_error_against_x() {
    let dir = tempfile::tempdir().unwrap();
    // Video accuracies 0.9, 0.8, 1.0: mean 90.0, population std
    // sqrt((0 + 0.01 + 0.01) / 3) = 8.165 -> "90.0 ± 8.2", error 10.0 ± 8.2.
    // Frames 0.8 in every run: 80.0 ± 0.0, without no_grasp 70.0 ± 0.0.
    let a = write_report(&dir.path().join("a"), &[(0.9, 0.8), (0.8, 0.8), (1.0, 0.8)]);
    // 0.5 and 0.7: 60.0 ± 10.0, error 40.0 ± 10.0; frames 0.6 and 0.8: 70.0 ± 10.0.
    let b = write_report(&dir.path().join("b"), &[(0.5, 0.6), (0.7, 0.8)]);
    let spec = SummarySpec {
        x_label: Some("samples".into()),
        log_x: true,
        reports: vec![
            entry("cycles-16", Some(16.0), &b.join("report.json")),
            entry("cycles-1", Some(1.0), &a),
        ],
        ..Default::default()
    };
    let s = Summary::load(spec).unwrap();
    let out = dir.path().join("out");
    s.write(&out).unwrap();
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(
        md.contains("| label | samples | runs | the hand's decision | per-video accuracy | per-video error |"),
        "{md}"
    );
    assert!(
        md.contains("| cycles-16 | 16 | 2 | 60.0 ± 10.0 | 60.0 ± 10.0 | 40.0 ± 10.0 | 70.0 ± 10.0 | 60.0 ± 10.0 | – | 75.0 ± 0.0 | 100.0 ± 0.0 | 40.0 ± 10.0 |"),
        "{md}"
    );
    assert!(
        md.contains(
            "| cycles-1 | 1 | 3 | 90.0 ± 8.2 | 90.0 ± 8.2 | 10.0 ± 8.2 | 80.0 ± 0.0 | 70.0 ± 0.0 | – | 75.0 ± 0.0 | 100.0 ± 0.0 | 70.0 ± 8.2 |"
        ),
        "{md}"
    );
    // Rows keep the order given.
    assert!(md.find("| cycles-16 |").unwrap() < md.find("| cycles-1 |").unwrap());
    assert!(md.contains("62 sequences (≤ 2 per pair)"), "{md}");
    assert!(
        md.contains("frozen backbone from runs/scratch/seed-0"),
        "{md}"
    );
    assert!((s.rows[1].video_error.std - (0.02f64 / 3.0).sqrt()).abs() < 1e-12);

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!((json["rows"][0]["video_error"]["mean"].as_f64().unwrap() - 0.4).abs() < 1e-12);

    // The plot is a PNG with the series drawn in its colour.
    let png = image::open(out.join("error.png")).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (800, 500));
    let blue = png.pixels().filter(|p| p.0 == [31, 119, 180]).count();
    assert!(blue > 100, "{blue} series pixels");
    // No temporary files left behind.
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
}

#[test]
fn conditions_as_columns() {
    let dir = tempfile::tempdir().unwrap();
    let r = |name: &str, v: f64| write_report(&dir.path().join(name), &[(v, 0.5)]);
    let spec = SummarySpec {
        by_condition: true,
        reports: vec![
            entry("fc/seated", None, &r("fs", 0.25)),
            entry("fc/night", None, &r("fn", 0.125)),
            entry("fc/default", None, &r("fd", 1.0)),
            entry("lstm/fast", None, &r("lf", 0.5)),
            entry("lstm/default", None, &r("ld", 0.75)),
        ],
        ..Default::default()
    };
    let s = Summary::load(spec).unwrap();
    assert!(!s.has_x());
    let md = s.markdown();
    // The paper's order first, unknown conditions after; models as given.
    assert!(
        md.contains("| model | default | fast | seated | night |"),
        "{md}"
    );
    assert!(
        md.contains("| fc | 100.0 ± 0.0 | – | 25.0 ± 0.0 | 12.5 ± 0.0 |"),
        "{md}"
    );
    assert!(
        md.contains("| lstm | 75.0 ± 0.0 | 50.0 ± 0.0 | – | – |"),
        "{md}"
    );
    assert!(md.find("| fc |").unwrap() < md.find("| lstm |").unwrap());
    s.write(&dir.path().join("out")).unwrap();
    assert!(!dir.path().join("out/error.png").exists());

    let twice = SummarySpec {
        by_condition: true,
        reports: vec![
            entry("fc/seated", None, &r("a", 0.5)),
            entry("fc/seated", None, &r("b", 0.5)),
        ],
        ..Default::default()
    };
    assert!(format!("{:#}", Summary::load(twice).unwrap_err()).contains("twice"));
    let flat = SummarySpec {
        by_condition: true,
        reports: vec![entry("seated", None, &r("c", 0.5))],
        ..Default::default()
    };
    assert!(format!("{:#}", Summary::load(flat).unwrap_err()).contains("MODEL/CONDITION"));
}

/// A by-condition summary of `reports` that chooses the model to ship.
fn shipping(reports: Vec<Entry>) -> SummarySpec {
    SummarySpec {
        by_condition: true,
        ship_by_worst: true,
        reports,
        ..Default::default()
    }
}

/// The shipped model is the one whose worst test set is best, not the one
/// best on its own conditions; ties go to the higher mean.
#[test]
fn the_shipped_model_is_chosen_by_its_worst_test_set() {
    let dir = tempfile::tempdir().unwrap();
    let r = |name: &str, v: f64| write_report(&dir.path().join(name), &[(v, 0.5)]);
    let spec = shipping;
    // tuned: best at home (0.98) but 0.75 abroad; frozen: 0.9 and 0.8;
    // even: 0.8 on both (the same worst as frozen, a lower mean).
    let s = Summary::load(spec(vec![
        entry("tuned/default", None, &r("td", 0.98)),
        entry("tuned/world_foreign", None, &r("tw", 0.75)),
        entry("even/default", None, &r("ed", 0.8)),
        entry("even/world_foreign", None, &r("ew", 0.8)),
        entry("frozen/default", None, &r("fd", 0.9)),
        entry("frozen/world_foreign", None, &r("fw", 0.8)),
    ]))
    .unwrap();
    let choice = s.choice.as_ref().unwrap();
    assert_eq!(choice.shipped, "frozen");
    let order: Vec<&str> = choice.standings.iter().map(|s| s.model.as_str()).collect();
    assert_eq!(order, ["frozen", "even", "tuned"]);
    assert_eq!(choice.standings[2].worst_set, "world_foreign");
    assert!((choice.standings[2].worst_hand_accuracy - 0.75).abs() < 1e-12);
    let md = s.markdown();
    assert!(
        md.contains(
            "| frozen (shipped) | world_foreign | 80.0 | 80.0 (world_foreign) | 85.0 | 85.0 |"
        ),
        "{md}"
    );
    let out = dir.path().join("out");
    s.write(&out).unwrap();
    assert_eq!(
        std::fs::read_to_string(out.join("shipped.txt")).unwrap(),
        "frozen\n"
    );

    // A model missing a test set cannot be judged on it.
    let err = Summary::load(spec(vec![
        entry("a/default", None, &r("ad", 0.9)),
        entry("a/world_foreign", None, &r("aw", 0.9)),
        entry("b/default", None, &r("bd", 0.9)),
    ]))
    .unwrap_err();
    assert!(
        format!("{err:#}").contains("b has no report on test set world_foreign"),
        "{err:#}"
    );
    let mut flat = spec(vec![entry("a/default", None, &r("x", 0.9))]);
    flat.by_condition = false;
    assert!(format!("{:#}", Summary::load(flat).unwrap_err()).contains("--by-condition"));
}

/// The ranking is by the hand's decision on the worst set, not by the
/// vote: a model whose vote holds up but whose hand falls back to the wrong
/// pre-shape loses; equal hands go to the better worst vote.
#[test]
fn the_hands_decision_ranks_before_the_vote() {
    let dir = tempfile::tempdir().unwrap();
    let r = |name: &str, vote: f64, hand: f64| {
        write_report_with_hand(&dir.path().join(name), &[(vote, 0.5, hand)])
    };
    // voter: votes 0.9 / 0.85, but the hand 0.9 / 0.7; steady: votes 0.9 /
    // 0.8, the hand 0.9 / 0.78; twin: steady's hand, a vote of 0.75 abroad.
    let s = Summary::load(shipping(vec![
        entry("voter/default", None, &r("vd", 0.9, 0.9)),
        entry("voter/world_foreign", None, &r("vw", 0.85, 0.7)),
        entry("twin/default", None, &r("td", 0.9, 0.9)),
        entry("twin/world_foreign", None, &r("tw", 0.75, 0.78)),
        entry("steady/default", None, &r("sd", 0.9, 0.9)),
        entry("steady/world_foreign", None, &r("sw", 0.8, 0.78)),
    ]))
    .unwrap();
    let choice = s.choice.as_ref().unwrap();
    let order: Vec<&str> = choice.standings.iter().map(|s| s.model.as_str()).collect();
    assert_eq!(order, ["steady", "twin", "voter"]);
    assert_eq!(choice.shipped, "steady");
    let md = s.markdown();
    assert!(md.contains("## The hand's decision (what hannes-run's policy commands) by test set"));
    assert!(md.contains("| voter | 90.0 ± 0.0 | 70.0 ± 0.0 |"), "{md}");
    // A report that predates the hand's decision cannot be ranked.
    let old = r("old", 0.9, 0.9).join("report.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&old).unwrap()).unwrap();
    json["aggregate"]
        .as_object_mut()
        .unwrap()
        .remove("hand_accuracy");
    std::fs::write(&old, json.to_string()).unwrap();
    let err = Summary::load(shipping(vec![
        entry("old/default", None, &old),
        entry("old/world_foreign", None, &old),
    ]))
    .unwrap_err();
    assert!(format!("{err:#}").contains("no hand's decision"), "{err:#}");
}

/// A head that reads sequences cannot drive the hand, so it never ships,
/// however good its worst set; with nothing else, the choice is refused.
#[test]
fn only_a_head_that_classifies_frames_ships() {
    let dir = tempfile::tempdir().unwrap();
    let r = |name: &str, v: f64, head: &str| {
        let dir = write_report(&dir.path().join(name), &[(v, 0.5)]);
        let file = dir.join("report.json");
        let mut report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
        report["head"] = head.into();
        std::fs::write(&file, report.to_string()).unwrap();
        dir
    };
    let spec = shipping;
    let s = Summary::load(spec(vec![
        entry("lstm/default", None, &r("ld", 0.95, "lstm")),
        entry("lstm/world_foreign", None, &r("lw", 0.9, "lstm")),
        entry("fc/default", None, &r("fd", 0.9, "fc")),
        entry("fc/world_foreign", None, &r("fw", 0.8, "fc")),
    ]))
    .unwrap();
    let choice = s.choice.as_ref().unwrap();
    assert_eq!(choice.shipped, "fc");
    assert_eq!(choice.standings[0].model, "lstm");
    assert!(!choice.standings[0].runs_on_hand() && choice.standings[1].runs_on_hand());
    let md = s.markdown();
    assert!(
        md.contains("| lstm (not shippable: its lstm head does not run on the hand) |")
            && md.contains("| fc (shipped) |"),
        "{md}"
    );
    let err = Summary::load(spec(vec![entry(
        "lstm/default",
        None,
        &r("only", 0.95, "lstm"),
    )]))
    .unwrap_err();
    assert!(
        format!("{err:#}").contains("no model can ship")
            && format!("{err:#}").contains("lstm (lstm)"),
        "{err:#}"
    );
}

/// The error of summarizing the one report `e`, with its causes.
fn load_error(e: Entry) -> String {
    let spec = SummarySpec {
        reports: vec![e],
        ..Default::default()
    };
    format!("{:#}", Summary::load(spec).unwrap_err())
}

#[test]
fn bad_reports_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nowhere");
    let err = load_error(entry("m", None, &missing));
    assert!(err.contains("`m`") && err.contains("nowhere"), "{err}");

    let empty = write_report(&dir.path().join("empty"), &[]);
    let err = load_error(entry("e", None, &empty));
    assert!(
        err.contains("video_accuracy") && err.contains("empty"),
        "{err}"
    );

    std::fs::write(dir.path().join("junk.json"), "{\"mode\": 3}").unwrap();
    let err = load_error(entry("j", None, &dir.path().join("junk.json")));
    assert!(err.contains("junk.json"), "{err}");

    let ok = write_report(&dir.path().join("ok"), &[(0.5, 0.5)]);
    let s = Summary::load(SummarySpec {
        log_x: true,
        reports: vec![entry("zero", Some(0.0), &ok)],
        ..Default::default()
    })
    .unwrap();
    let err = format!("{:#}", s.write(&dir.path().join("out")).unwrap_err());
    assert!(err.contains("zero") && err.contains("log"), "{err}");
}

#[test]
fn command_line_and_toml_list() {
    let dir = tempfile::tempdir().unwrap();
    write_report(&dir.path().join("runs/q1"), &[(0.5, 0.5)]);
    write_report(&dir.path().join("runs/q4"), &[(0.75, 0.5)]);
    // Paths relative to the list file's directory.
    std::fs::write(
        dir.path().join("list.toml"),
        "title = \"Error against samples\"\nx_label = \"samples\"\n\
         [[report]]\nlabel = \"q1\"\nx = 1\npath = \"runs/q1\"\n",
    )
    .unwrap();
    let q4 = format!("q4=4:{}", dir.path().join("runs/q4").display());
    let out = dir.path().join("out");
    let status = grasp_test_support::Program::new(env!("CARGO_BIN_EXE_grasp-train"))
        .command(["summarize"])
        .arg("--list")
        .arg(dir.path().join("list.toml"))
        .args(["--report", &q4, "--log-x", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(md.starts_with("# Error against samples"), "{md}");
    assert!(
        md.contains("| q1 | 1 | 1 | 50.0 ± 0.0 | 50.0 ± 0.0 | 50.0 ± 0.0 |"),
        "{md}"
    );
    assert!(
        md.contains("| q4 | 4 | 1 | 75.0 ± 0.0 | 75.0 ± 0.0 | 25.0 ± 0.0 |"),
        "{md}"
    );
    assert!(out.join("error.png").is_file());

    std::fs::write(
        dir.path().join("typo.toml"),
        "[[report]]\nlabel = \"a\"\npth = \"x\"\n",
    )
    .unwrap();
    let o = grasp_test_support::Program::new(env!("CARGO_BIN_EXE_grasp-train"))
        .command(["summarize"])
        .arg("--list")
        .arg(dir.path().join("typo.toml"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("typo.toml") && err.contains("pth"), "{err}");
}

/// A one-run report whose per-part accuracies are `(part, accuracy)`, on
/// the mug (a multi-grasp object).
fn write_part_report(dir: &Path, video: f64, parts: &[(&str, f64)]) -> PathBuf {
    use grasp_schema::taxonomy::Preshape;
    use trainer::eval::metrics::PartAccuracy;
    let per_part = parts
        .iter()
        .map(|(part, acc)| PartAccuracy {
            object: "025_mug".into(),
            part: part.to_string(),
            preshape: if *part == "handle" {
                Preshape::Pinch3
            } else {
                Preshape::Power
            },
            videos: 4,
            correct_videos: (acc * 4.0) as usize,
            video_accuracy: *acc,
            grasp_frames: 40,
            frame_accuracy: Some(*acc),
        })
        .collect();
    let run = RunReport {
        checkpoint: "run/seed-0".into(),
        seed: 0,
        metrics: Metrics {
            videos: 8,
            video_accuracy: video,
            per_part,
            ..Default::default()
        },
        videos: Vec::new(),
    };
    let r = Report::new("frozen-pretrained", "fc", Path::new("data/test"), vec![run]);
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(
        dir.join("report.json"),
        serde_json::to_string_pretty(&r).unwrap(),
    )
    .unwrap();
    dir.to_path_buf()
}

#[test]
fn per_part_accuracy_by_condition_with_unseen_look_as_a_column() {
    let dir = tempfile::tempdir().unwrap();
    let d = write_part_report(
        &dir.path().join("d"),
        0.75,
        &[("body", 1.0), ("handle", 0.5)],
    );
    let u = write_part_report(
        &dir.path().join("u"),
        0.5,
        &[("body", 0.75), ("handle", 0.25)],
    );
    let spec = SummarySpec {
        by_condition: true,
        reports: vec![
            entry("fc/unseen_look", None, &u),
            entry("fc/default", None, &d),
        ],
        ..Default::default()
    };
    let md = Summary::load(spec).unwrap().markdown();
    assert!(md.contains("| model | default | unseen_look |"), "{md}");
    assert!(md.contains("| fc | 75.0 ± 0.0 | 50.0 ± 0.0 |"), "{md}");
    assert!(
        md.contains("| model | object | part | pre-shape | default | unseen_look |"),
        "{md}"
    );
    assert!(
        md.contains("| fc | 025_mug | handle | pinch3 | 50.0 ± 0.0 | 25.0 ± 0.0 |"),
        "{md}"
    );
    assert!(
        md.contains("| fc | 025_mug | body | power | 100.0 ± 0.0 | 75.0 ± 0.0 |"),
        "{md}"
    );
    // Without by-condition: the reports as columns.
    let flat = SummarySpec {
        reports: vec![entry("a", None, &d), entry("b", None, &u)],
        ..Default::default()
    };
    let md = Summary::load(flat).unwrap().markdown();
    assert!(md.contains("| object | part | pre-shape | a | b |"), "{md}");
    assert!(
        md.contains("| 025_mug | handle | pinch3 | 50.0 ± 0.0 | 25.0 ± 0.0 |"),
        "{md}"
    );
}
