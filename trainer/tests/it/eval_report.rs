//! The report's numbers on a hand-made case: predictions and labels built by
//! hand, expected accuracies computed by hand below.

use grasp_schema::taxonomy::{Class, Preshape};
use trainer::eval::metrics::{FrameWindow, VideoOutcome};
use trainer::eval::report::RunReport;
use trainer::eval::{compute_metrics, write_report, Report, VideoPrediction};

const P: [f32; 5] = [0.7, 0.1, 0.1, 0.05, 0.05]; // power
const L: [f32; 5] = [0.1, 0.7, 0.1, 0.05, 0.05]; // lateral
const N: [f32; 5] = [0.05, 0.05, 0.1, 0.1, 0.7]; // no_grasp
const Q: [f32; 5] = [0.1, 0.05, 0.1, 0.7, 0.05]; // pinch3

fn video(
    id: &str,
    object: &str,
    preshape: Preshape,
    multi: bool,
    probs: Vec<[f32; 5]>,
) -> VideoPrediction {
    let n = probs.len();
    // Last frame labelled no_grasp, the others the video's pre-shape.
    let labels = (0..n)
        .map(|i| {
            if i + 1 == n {
                Class::NoGrasp
            } else {
                Class::from(preshape)
            }
        })
        .collect();
    VideoPrediction {
        id: id.into(),
        object: object.into(),
        part: Some(format!("{object}-{}", preshape.name())),
        preshape,
        multi_grasp: multi,
        labels,
        probs,
        times_s: (0..n).map(|i| i as f64 * 0.5).collect(),
    }
}

/// Four videos of four frames (times 0, 0.5, 1.0, 1.5 s):
/// - a: mug (multi), power.   frames P P L N -> vote power (2-1): right.
///   frame hits: P=P, P=P, L!=P, N=N -> 3/4; without no_grasp 2/3.
/// - b: mug (multi), lateral. frames P P L N -> vote power: wrong.
///   hits: P!=L, P!=L, L=L, N=N -> 2/4; without 1/3.
/// - c: mug (multi), lateral. frames L N N N -> vote lateral: right.
///   hits: L, N!=L, N!=L, N=N -> 2/4; without 1/3.
/// - d: marker (single), pinch3. frames Q Q Q P -> vote pinch3: right.
///   hits: Q, Q, Q, P!=N -> 3/4; without 3/3.
fn videos() -> Vec<VideoPrediction> {
    vec![
        video("a", "mug", Preshape::Power, true, vec![P, P, L, N]),
        video("b", "mug", Preshape::Lateral, true, vec![P, P, L, N]),
        video("c", "mug", Preshape::Lateral, true, vec![L, N, N, N]),
        video("d", "marker", Preshape::Pinch3, false, vec![Q, Q, Q, P]),
    ]
}

#[test]
fn hand_made_case_gives_hand_computed_numbers() {
    let m = compute_metrics(&videos(), 0.5, &Default::default());
    // Frames: (3 + 2 + 2 + 3) / 16 correct.
    assert_eq!(m.frames, 16);
    assert!((m.frame_accuracy - 10.0 / 16.0).abs() < 1e-12);
    // Without no_grasp frames: (2 + 1 + 1 + 3) / 12.
    assert_eq!(m.grasp_frames, 12);
    assert!((m.frame_accuracy_without_no_grasp - 7.0 / 12.0).abs() < 1e-12);
    // Videos: a, c, d right; b wrong.
    assert!((m.video_accuracy - 0.75).abs() < 1e-12);
    assert_eq!(m.video_accuracy_single, Some(1.0));
    assert!((m.video_accuracy_multi.unwrap() - 2.0 / 3.0).abs() < 1e-12);
    // Video confusion: power->power 1, lateral->power 1, lateral->lateral 1,
    // pinch3->pinch3 1.
    assert_eq!(m.video_confusion[0][0], 1);
    assert_eq!(m.video_confusion[1][0], 1);
    assert_eq!(m.video_confusion[1][1], 1);
    assert_eq!(m.video_confusion[3][3], 1);
    // Frame confusion row no_grasp (4 frames): 3 predicted no_grasp, 1 power.
    assert_eq!(m.frame_confusion[4], vec![1, 0, 0, 0, 3]);
    // Baseline: the mug's most frequent pre-shape is lateral (2 of 3), the
    // marker's pinch3: right on b, c, d -> 3/4; multi 2/3, single 1.
    assert_eq!(m.baseline.object_preshape["mug"], Preshape::Lateral);
    assert!((m.baseline.video_accuracy - 0.75).abs() < 1e-12);
    assert!((m.baseline.video_accuracy_multi.unwrap() - 2.0 / 3.0).abs() < 1e-12);
    // Accuracy against time counts the pre-shape frames only (frame right if
    // it equals the video's pre-shape). Multi-grasp videos a, b, c at t = 0:
    // P/power yes, P/lateral no, L/lateral yes -> 2/3; at 0.5 s: P/power
    // yes, P/lateral no, N/lateral (an abstention) -> 1/3, no_grasp 1/3; at
    // 1.5 s every frame is labelled no_grasp: no point.
    let multi = m.time.multi.accuracy();
    assert!((multi[0].unwrap() - 2.0 / 3.0).abs() < 1e-12);
    assert!((multi[1].unwrap() - 1.0 / 3.0).abs() < 1e-12);
    let abstained = m.time.multi.no_grasp_share();
    assert_eq!(abstained[0], Some(0.0));
    assert!((abstained[1].unwrap() - 1.0 / 3.0).abs() < 1e-12);
    assert_eq!(multi.get(3).copied().flatten(), None);
    // Single-grasp video d: Q Q Q on its pre-shape frames; the P on its
    // no_grasp frame is not on the curve.
    assert_eq!(
        m.time.single.accuracy(),
        vec![Some(1.0), Some(1.0), Some(1.0)]
    );
    // The last second before contact (1.5 s in every video): frames at 0.5
    // and 1.0 s. a: P yes, L no; b: P no, L yes; c: N no, N no; d: Q, Q.
    assert_eq!(m.last_second_frames, 8);
    assert_eq!(m.last_second_accuracy, Some(0.5));
    // The hand's decision (hannes-run's defaults: 2 s window, 3 votes at
    // least, half of them, mean probability 0.5, fallback power): a power
    // (right), b power (wrong), c one lateral vote -> too few -> the power
    // fallback (wrong, although the vote was right), d pinch3 (right).
    assert!((m.hand.accuracy - 0.5).abs() < 1e-12);
    assert_eq!(m.hand.accuracy_single, Some(1.0));
    assert!((m.hand.accuracy_multi.unwrap() - 1.0 / 3.0).abs() < 1e-12);
    use grasp_policy::OutcomeKind;
    assert_eq!(m.hand.outcomes[&OutcomeKind::Majority], 3);
    assert_eq!(m.hand.outcomes[&OutcomeKind::Fallback], 1);
    assert_eq!(m.hand.mean_decision_s, Some(1.5));
    let c = VideoOutcome::of(&videos()[2], &Default::default());
    let hand = c.hand.unwrap();
    assert_eq!(
        (c.vote, hand.preshape),
        (Preshape::Lateral, Some(Preshape::Power))
    );
    assert!(hand.why.unwrap().contains("fewer than 3"), "names why");
    // Without a fallback the same video commands nothing: wrong as well.
    let none = grasp_policy::PolicyConfig {
        fallback: None,
        ..Default::default()
    };
    let m = compute_metrics(&videos(), 0.5, &none);
    assert_eq!(m.hand.outcomes[&OutcomeKind::NoCommand], 1);
    assert!((m.hand.accuracy - 0.5).abs() < 1e-12);
}

#[test]
fn report_aggregates_seeds_and_writes_its_files() {
    let m1 = compute_metrics(&videos(), 0.5, &Default::default());
    // Second "seed": video b now right (frames L L L N): video accuracy 1.
    let mut v2 = videos();
    v2[1].probs = vec![L, L, L, N];
    let m2 = compute_metrics(&v2, 0.5, &Default::default());
    assert_eq!(m2.video_accuracy, 1.0);
    let runs = vec![
        RunReport {
            checkpoint: "s0".into(),
            seed: 0,
            metrics: m1,
            videos: videos()
                .iter()
                .map(|v| VideoOutcome::of(v, &Default::default()))
                .collect(),
        },
        RunReport {
            checkpoint: "s1".into(),
            seed: 1,
            metrics: m2,
            videos: v2
                .iter()
                .map(|v| VideoOutcome::of(v, &Default::default()))
                .collect(),
        },
    ];
    let r = Report::new(
        "frozen-pretrained",
        "fc",
        std::path::Path::new("data"),
        runs,
    );
    // Mean of 0.75 and 1.0 is 0.875, population std 0.125.
    let v = r.aggregate["video_accuracy"];
    assert!((v.mean - 0.875).abs() < 1e-12);
    assert!((v.std - 0.125).abs() < 1e-12);
    assert_eq!(v.n, 2);
    let dir = tempfile::tempdir().unwrap();
    write_report(&r, dir.path()).unwrap();
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("**Mode: frozen-pretrained**"));
    assert!(md.contains("| per-video (majority vote, no_grasp excluded) | 87.5 ± 12.5 |"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(json["mode"], "frozen-pretrained");
    assert_eq!(json["runs"].as_array().unwrap().len(), 2);
    // videos.csv: b is voted power by the first seed, lateral by the second.
    let csv = std::fs::read_to_string(dir.path().join("videos.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    // The hand's decision beside it: c's one lateral vote is too few, so
    // the hand gets the power fallback in both seeds.
    assert_eq!(
        rows[0],
        "id,object,part,truth,vote_seed0,vote_seed1,hand_seed0,hand_seed1"
    );
    assert_eq!(rows[1], "a,mug,mug-power,power,power,power,power,power");
    assert_eq!(
        rows[2],
        "b,mug,mug-lateral,lateral,power,lateral,power,lateral"
    );
    assert_eq!(
        rows[3],
        "c,mug,mug-lateral,lateral,lateral,lateral,power (fallback),power (fallback)"
    );
    assert_eq!(
        rows[4],
        "d,marker,marker-pinch3,pinch3,pinch3,pinch3,pinch3,pinch3"
    );
    assert_eq!(rows.len(), 5);
    for png in ["time_accuracy.png", "confusion.png"] {
        let img = image::open(dir.path().join(png)).unwrap();
        assert!(img.width() > 100);
    }
}

#[test]
fn per_part_accuracy_of_the_multi_grasp_objects() {
    // Mug parts: "mug-power" holds a (right); "mug-lateral" holds b (wrong)
    // and c (right). The marker is single-grasp: no per-part row.
    let m = compute_metrics(&videos(), 0.5, &Default::default());
    let parts: Vec<(&str, &str, usize, f64)> = m
        .per_part
        .iter()
        .map(|p| {
            (
                p.object.as_str(),
                p.part.as_str(),
                p.videos,
                p.video_accuracy,
            )
        })
        .collect();
    assert_eq!(
        parts,
        vec![("mug", "mug-lateral", 2, 0.5), ("mug", "mug-power", 1, 1.0)]
    );
    // Frames of the pre-shape: lateral b (P P L) 1/3 and c (L N N) 1/3.
    assert!((m.per_part[0].frame_accuracy.unwrap() - 2.0 / 6.0).abs() < 1e-12);
    // Videos without a part (the authors' real layout) give no rows.
    let mut real = videos();
    for v in &mut real {
        v.part = None;
    }
    assert!(compute_metrics(&real, 0.5, &Default::default())
        .per_part
        .is_empty());
    // In the report: mean ± std over runs, and a Markdown section.
    let mut v2 = videos();
    v2[1].probs = vec![L, L, L, N]; // b right in the second run
    let runs = [videos(), v2]
        .iter()
        .enumerate()
        .map(|(seed, v)| RunReport {
            checkpoint: format!("s{seed}").into(),
            seed: seed as u64,
            metrics: compute_metrics(v, 0.5, &Default::default()),
            videos: Vec::new(),
        })
        .collect();
    let r = Report::new("frozen-pretrained", "fc", std::path::Path::new("d"), runs);
    let lateral = &r.per_part[0];
    assert_eq!(lateral.part, "mug-lateral");
    assert!((lateral.video_accuracy.mean - 0.75).abs() < 1e-12);
    assert!((lateral.video_accuracy.std - 0.25).abs() < 1e-12);
    let md = trainer::eval::report::markdown(&r);
    assert!(
        md.contains("| mug | mug-lateral | lateral | 2 | 75.0 ± 25.0 |"),
        "{md}"
    );
}

#[test]
fn a_frame_window_scores_only_its_frames() {
    // Video b: frames at 0, 0.5, 1.0 (P P L) then the no_grasp tail at 1.5.
    let b = &videos()[1];
    // The last 0.5 s before the tail: the frame at 1.0 s only (L: right).
    let w = FrameWindow {
        before_tail_s: Some(0.5),
        ..Default::default()
    };
    let kept = w.apply(b).unwrap();
    assert_eq!(kept.times_s, vec![1.0]);
    assert_eq!(kept.probs, vec![L]);
    // Absolute bounds: [0.5, 1.5) keeps 0.5 and 1.0.
    let w = FrameWindow {
        from_s: Some(0.5),
        to_s: Some(1.5),
        ..Default::default()
    };
    assert_eq!(w.apply(b).unwrap().times_s, vec![0.5, 1.0]);
    // A window past the end keeps nothing.
    let late = FrameWindow {
        from_s: Some(9.0),
        ..Default::default()
    };
    assert!(late.apply(b).is_none());
    assert!(FrameWindow::default().apply(b).unwrap() == *b);
    // Scored over the last 0.5 s before the tail (the frame at 1.0 s):
    let windowed: Vec<_> = videos()
        .iter()
        .filter_map(|v| {
            FrameWindow {
                before_tail_s: Some(0.5),
                ..Default::default()
            }
            .apply(v)
        })
        .collect();
    let m = compute_metrics(&windowed, 0.5, &Default::default());
    // a: L (wrong for power), b: L (right), c: N, no pre-shape vote, the
    // most mass goes to pinch (wrong), d: Q (right) -> 2/4.
    assert_eq!(m.videos, 4);
    assert!(
        (m.video_accuracy - 0.5).abs() < 1e-12,
        "{}",
        m.video_accuracy
    );
    let bad = FrameWindow {
        from_s: Some(2.0),
        to_s: Some(1.0),
        ..Default::default()
    };
    assert!(bad.validate().is_err());
}

/// report.html on a hand-made case: every frame of every synthetic video
/// predicted `power`. The videos of other pre-shapes (a wrong vote) come
/// first; each frame's mark says right on a power video's pre-shape
/// frames, wrong on its `no_grasp` tail; every video has its strip with
/// the model's crop.
#[test]
fn report_page_puts_the_wrong_videos_first_with_every_frames_answer() {
    use trainer::data::synthetic::{write_synthetic, Layout, SyntheticSpec};
    use trainer::data::{read_dataset, BadData, OnBadData, ReaderOptions};
    let dir = tempfile::tempdir().unwrap();
    let spec = SyntheticSpec::small(Layout::Generated);
    write_synthetic(&dir.path().join("data"), &spec).unwrap();
    let opts = ReaderOptions {
        crop: grasp_model::input::Crop::Fraction(0.5),
        ..Default::default()
    };
    let bad = BadData::new(OnBadData::Fail);
    let data = read_dataset(&dir.path().join("data"), &opts, &bad).unwrap();
    let multi = data.multi_grasp_objects();
    let preds: Vec<VideoPrediction> = data
        .sequences
        .iter()
        .map(|s| VideoPrediction {
            id: s.id.clone(),
            object: s.object.clone(),
            part: s.part.clone(),
            preshape: s.preshape,
            multi_grasp: multi.contains(&s.object),
            labels: s.labels.clone(),
            probs: vec![P; s.frames.len()],
            times_s: (0..s.frames.len()).map(|i| s.time_s(i)).collect(),
        })
        .collect();
    let mut frames = trainer::eval::html::FrameRecord::new(&data);
    frames.add_run(&preds);
    let run = RunReport {
        checkpoint: "s0".into(),
        seed: 0,
        metrics: compute_metrics(&preds, 0.1, &Default::default()),
        videos: preds
            .iter()
            .map(|v| VideoOutcome::of(v, &Default::default()))
            .collect(),
    };
    let mut r = Report::new("from-scratch", "fc", &dir.path().join("data"), vec![run]);
    r.frames = Some(std::sync::Arc::new(frames));
    let out = dir.path().join("out");
    write_report(&r, &out).unwrap();
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let articles: Vec<&str> = html.split("<article class=\"video\"").skip(1).collect();
    assert_eq!(articles.len(), preds.len());
    let truth = |a: &str| {
        a.split("data-truth=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .to_string()
    };
    let order: Vec<String> = articles.iter().map(|a| truth(a)).collect();
    let first_power = order.iter().position(|t| t == "power").unwrap();
    assert!(first_power > 0, "{order:?}");
    assert!(
        order[first_power..].iter().all(|t| t == "power"),
        "{order:?}"
    );
    let per_video = spec.frames - spec.no_grasp_frames;
    for a in &articles {
        assert!(
            a.contains("<img class=\"frames\"") && a.contains("centre 0.50"),
            "{a}"
        );
        let (ok, bad) = (
            a.matches("class=\"m ok\"").count(),
            a.matches("class=\"m bad\"").count(),
        );
        if truth(a) == "power" {
            assert_eq!((ok, bad), (per_video, spec.no_grasp_frames), "{a}");
        } else {
            assert_eq!((ok, bad), (0, spec.frames), "{a}");
        }
    }
}
