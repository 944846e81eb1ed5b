//! The evaluation report: `report.json` (everything), `report.md` (tables),
//! `time_accuracy.png` (the paper's Fig. 5) and `confusion.png`.

use super::metrics::{mean_std, scalars, Curve, FrameWindow, MeanStd, Metrics};
use grasp_schema::taxonomy::{Class, Preshape};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunReport {
    pub checkpoint: PathBuf,
    pub seed: u64,
    pub metrics: Metrics,
    /// Every scored video's vote (`videos.csv`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub videos: Vec<super::metrics::VideoOutcome>,
}

/// One part of a multi-grasp object over the runs of a report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartSummary {
    pub object: String,
    pub part: String,
    pub preshape: Preshape,
    /// Videos of the part per run.
    pub videos: usize,
    /// Per-video accuracy, mean ± std over runs.
    pub video_accuracy: MeanStd,
    /// Per-frame accuracy on the part's pre-shape frames.
    pub frame_accuracy: Option<MeanStd>,
}

/// Mean ± std over runs of each part's accuracy, in (object, part) order.
pub fn part_summaries(runs: &[RunReport]) -> Vec<PartSummary> {
    let mut by_part: BTreeMap<(String, String), Vec<&super::metrics::PartAccuracy>> =
        BTreeMap::new();
    for r in runs {
        for p in &r.metrics.per_part {
            by_part
                .entry((p.object.clone(), p.part.clone()))
                .or_default()
                .push(p);
        }
    }
    by_part
        .into_iter()
        .filter_map(|((object, part), ps)| {
            let video: Vec<f64> = ps.iter().map(|p| p.video_accuracy).collect();
            let frame: Vec<f64> = ps.iter().filter_map(|p| p.frame_accuracy).collect();
            Some(PartSummary {
                preshape: ps.first()?.preshape,
                videos: ps.first()?.videos,
                video_accuracy: mean_std(&video)?,
                frame_accuracy: mean_std(&frame),
                object,
                part,
            })
        })
        .collect()
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    /// `frozen-pretrained` or `from-scratch` (every run of a report shares it).
    pub mode: String,
    /// Which backbone produced the report: "frozen mobilenet-v2 from
    /// runs/scratch/seed-0", "frozen efficientnet-lite0 PATH" or
    /// "mobilenet-v2 trained from scratch".
    #[serde(default)]
    pub backbone: String,
    pub head: String,
    /// The training set: its `sequences_per_pair` cap and size (first run).
    #[serde(default)]
    pub sequences_per_pair: Option<usize>,
    #[serde(default)]
    pub train_sequences: Option<usize>,
    pub dataset: PathBuf,
    pub runs: Vec<RunReport>,
    /// Mean ± std over runs of each headline scalar.
    pub aggregate: BTreeMap<String, MeanStd>,
    /// Frame and video confusion summed over runs; time curves summed.
    pub frame_confusion: Vec<Vec<u64>>,
    pub video_confusion: Vec<Vec<u64>>,
    pub time_bin_s: f64,
    pub time_single: Curve,
    pub time_multi: Curve,
    /// The frames scored (every frame unless restricted by `eval`).
    #[serde(default)]
    pub window: FrameWindow,
    /// Videos left out because no frame of theirs lies in the window.
    #[serde(default)]
    pub videos_outside_window: usize,
    /// The policy the hand's decision was taken with (None in reports
    /// written before it was scored).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub policy: Option<grasp_policy::PolicyConfig>,
    /// Lead-in frames (before the target entered the view) dropped before
    /// inference; None when `eval --keep-lead-in` kept them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lead_in_trimmed: Option<LeadInTrim>,
    /// Further dataset roots pooled with `dataset` (`eval --data A --data
    /// B`: several test draws scored as one set).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pooled_with: Vec<PathBuf>,
    /// Per-part accuracy of the multi-grasp objects, over runs.
    #[serde(default)]
    pub per_part: Vec<PartSummary>,
    /// Bad data left out (`--on-bad-data skip`): how much, and where listed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bad_data: Option<BadDataNote>,
    /// How frames became the backbone's input (`eval`): the checkpoints'
    /// record, the lens given, and any flag that replaced part of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input: Option<InputRecord>,
    /// Every scored frame's place and each run's answer on it, for
    /// report.html's strips (kept by `eval`; not in report.json).
    #[serde(skip)]
    pub frames: Option<std::sync::Arc<super::html::FrameRecord>>,
}

/// The input record an evaluation used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputRecord {
    pub spec: grasp_model::input::InputSpec,
    /// The lens given for frames without sequence.json (theirs is used
    /// where they have one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lens: Option<grasp_model::input::Lens>,
    /// What replaced the checkpoint's record, e.g. `--center-crop 0.5
    /// replaced the checkpoint's crop (18.3 degrees)`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub overrides: Vec<String>,
}

impl InputRecord {
    /// One line for report.md.
    pub fn describe(&self) -> String {
        let mut line = format!("input: {}", self.spec.describe());
        if let Some(lens) = &self.lens {
            line += &format!(
                "; lens for frames without sequence.json: {}",
                lens.describe()
            );
        }
        if self.overrides.is_empty() {
            line += " (the checkpoint's)";
        }
        for o in &self.overrides {
            line += &format!("; {o}");
        }
        line
    }
}

/// What the lead-in trim dropped: frames, and the videos they came from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LeadInTrim {
    pub videos: usize,
    pub frames: usize,
}

/// Problems skipped while reading or evaluating the data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BadDataNote {
    pub skipped: usize,
    /// `problems.json`, relative to the report's folder.
    pub listed_in: PathBuf,
}

impl Report {
    pub fn new(mode: &str, head: &str, dataset: &Path, runs: Vec<RunReport>) -> Report {
        let mut aggregate = BTreeMap::new();
        if let Some(first) = runs.first() {
            for (i, (name, _)) in scalars(&first.metrics).into_iter().enumerate() {
                let vals: Vec<f64> = runs
                    .iter()
                    .filter_map(|r| scalars(&r.metrics)[i].1)
                    .collect();
                if let Some(ms) = mean_std(&vals) {
                    aggregate.insert(name.to_string(), ms);
                }
            }
        }
        let mut fc = vec![vec![0; Class::COUNT]; Class::COUNT];
        let mut vc = vec![vec![0; 4]; 4];
        let (mut single, mut multi) = (Curve::default(), Curve::default());
        for r in &runs {
            add_matrix(&mut fc, &r.metrics.frame_confusion);
            add_matrix(&mut vc, &r.metrics.video_confusion);
            single.merge(&r.metrics.time.single);
            multi.merge(&r.metrics.time.multi);
        }
        let per_part = part_summaries(&runs);
        Report {
            mode: mode.to_string(),
            backbone: String::new(),
            head: head.to_string(),
            sequences_per_pair: None,
            train_sequences: None,
            dataset: dataset.to_path_buf(),
            time_bin_s: runs.first().map(|r| r.metrics.time.bin_s).unwrap_or(0.1),
            runs,
            aggregate,
            frame_confusion: fc,
            video_confusion: vc,
            time_single: single,
            time_multi: multi,
            bad_data: None,
            window: FrameWindow::default(),
            videos_outside_window: 0,
            policy: None,
            lead_in_trimmed: None,
            pooled_with: Vec::new(),
            input: None,
            frames: None,
            per_part,
        }
    }
}

fn add_matrix(acc: &mut [Vec<u64>], m: &[Vec<u64>]) {
    for (a, r) in acc.iter_mut().zip(m) {
        for (x, y) in a.iter_mut().zip(r) {
            *x += y;
        }
    }
}

/// One row per video: what it shows and each run's vote, to find the
/// videos a model gets wrong.
pub fn videos_csv(report: &Report) -> String {
    let mut s = String::from("id,object,part,truth");
    for r in &report.runs {
        let _ = write!(s, ",vote_seed{}", r.seed);
    }
    for r in &report.runs {
        let _ = write!(s, ",hand_seed{}", r.seed);
    }
    s.push('\n');
    let Some(first) = report.runs.first() else {
        return s;
    };
    for (i, v) in first.videos.iter().enumerate() {
        let _ = write!(
            s,
            "{},{},{},{}",
            csv_field(&v.id),
            csv_field(&v.object),
            csv_field(v.part.as_deref().unwrap_or("")),
            v.truth.name()
        );
        let outcomes: Vec<_> = report
            .runs
            .iter()
            .map(|r| r.videos.get(i).filter(|o| o.id == v.id))
            .collect();
        for o in &outcomes {
            let _ = write!(s, ",{}", o.map_or("", |o| o.vote.name()));
        }
        for o in &outcomes {
            let hand = o.and_then(|o| o.hand.as_ref());
            let _ = write!(s, ",{}", hand.map_or(String::new(), hand_cell));
        }
        s.push('\n');
    }
    s
}

/// The hand's decision in a CSV cell: the pre-shape, with how when not by
/// the majority (`power (fallback)`), or `none (no_command)`.
fn hand_cell(h: &super::metrics::HandDecision) -> String {
    let name = h.preshape.map_or("none", |p| p.name());
    match h.how {
        grasp_policy::OutcomeKind::Majority => name.to_string(),
        how => format!("{name} ({})", how.name()),
    }
}

/// A CSV field, quoted when it holds a comma, quote or line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn pct(v: Option<f64>) -> String {
    v.map(|v| format!("{:.1}", v * 100.0))
        .unwrap_or_else(|| "–".into())
}

fn pct_ms(m: Option<&MeanStd>) -> String {
    m.map(|m| format!("{:.1} ± {:.1}", m.mean * 100.0, m.std * 100.0))
        .unwrap_or_else(|| "–".into())
}

pub fn markdown(report: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Evaluation report\n");
    let _ = writeln!(
        s,
        "- **Mode: {}** (head: {}{})\n- Dataset: `{}`\n- Videos: {} per run; runs (seeds): {}\n",
        report.mode,
        report.head,
        if report.backbone.is_empty() {
            String::new()
        } else {
            format!("; {}", report.backbone)
        },
        report.dataset.display(),
        report.runs.first().map(|x| x.metrics.videos).unwrap_or(0),
        report.runs.len()
    );
    if !report.window.is_all() {
        let _ = writeln!(
            s,
            "- **Frames scored: {}** ({} video(s) with no frame in the window left out)\n",
            report.window.describe(),
            report.videos_outside_window
        );
    }
    if !report.pooled_with.is_empty() {
        let roots: Vec<String> = report
            .pooled_with
            .iter()
            .map(|r| format!("`{}`", r.display()))
            .collect();
        let _ = writeln!(
            s,
            "- **Pooled** with {} ({} test sets scored as one)\n",
            roots.join(", "),
            roots.len() + 1
        );
    }
    if let Some(input) = &report.input {
        let _ = writeln!(s, "- Checkpoints' {}\n", input.describe());
    }
    if let Some(t) = report.lead_in_trimmed.filter(|t| t.frames > 0) {
        let _ = writeln!(
            s,
            "- Lead-in trimmed before inference: {} frame(s) of {} video(s) in which the \
             wrist camera did not yet see the target (the paper trims its from-ground \
             videos so; `eval --keep-lead-in` keeps them)\n",
            t.frames, t.videos
        );
    }
    if let Some(n) = report.train_sequences {
        let cap = report
            .sequences_per_pair
            .map(|k| format!(" (at most {k} per object-part pair)"))
            .unwrap_or_default();
        let _ = writeln!(s, "- Training set: {n} sequences{cap}\n");
    }
    if let Some(b) = &report.bad_data {
        let _ = writeln!(
            s,
            "- **Bad data skipped: {} problem(s)** (unreadable images, missing labels or \
             frames), listed in [`{}`]({}); the numbers below leave them out.\n",
            b.skipped,
            b.listed_in.display(),
            b.listed_in.display()
        );
    }
    let _ = writeln!(
        s,
        "## Accuracy (%), mean ± std over {} run(s)\n",
        report.runs.len()
    );
    let _ = writeln!(s, "| metric | value |\n|---|---|");
    let rows = [
        (
            "the hand's decision (hannes-run's policy on each video)",
            "hand_accuracy",
        ),
        (
            "the hand's decision, single-grasp objects",
            "hand_accuracy_single",
        ),
        (
            "the hand's decision, multi-grasp objects",
            "hand_accuracy_multi",
        ),
        (
            "per-video (majority vote, no_grasp excluded)",
            "video_accuracy",
        ),
        ("per-video, single-grasp objects", "video_accuracy_single"),
        ("per-video, multi-grasp objects", "video_accuracy_multi"),
        ("per-frame, with no_grasp", "frame_accuracy"),
        (
            "per-frame, without no_grasp frames",
            "frame_accuracy_without_no_grasp",
        ),
        (
            "per-frame, pre-shape frames in the last second before contact",
            "last_second_accuracy",
        ),
        (
            "baseline: perfect object classifier",
            "baseline_video_accuracy",
        ),
    ];
    for (label, key) in rows {
        let _ = writeln!(s, "| {label} | {} |", pct_ms(report.aggregate.get(key)));
    }
    hand_section(&mut s, report);
    let _ = writeln!(
        s,
        "\n## Runs\n\n| seed | checkpoint | hand | video | single | multi | frame | frame w/o no_grasp | baseline |\n|---|---|---|---|---|---|---|---|---|"
    );
    for run in &report.runs {
        let m = &run.metrics;
        let _ = writeln!(
            s,
            "| {} | `{}` | {} | {} | {} | {} | {} | {} | {} |",
            run.seed,
            run.checkpoint.display(),
            pct(Some(m.hand.accuracy)),
            pct(Some(m.video_accuracy)),
            pct(m.video_accuracy_single),
            pct(m.video_accuracy_multi),
            pct(Some(m.frame_accuracy)),
            pct(Some(m.frame_accuracy_without_no_grasp)),
            pct(Some(m.baseline.video_accuracy)),
        );
    }
    part_table(&mut s, report);
    let names: Vec<&str> = Class::names();
    let _ = writeln!(
        s,
        "\n## Frame confusion (rows: truth, columns: prediction; summed over runs)\n"
    );
    matrix(&mut s, &report.frame_confusion, &names);
    let pre: Vec<&str> = Preshape::ALL.iter().map(|p| p.name()).collect();
    let _ = writeln!(
        s,
        "\n## Video confusion (rows: truth, columns: vote; summed over runs)\n"
    );
    matrix(&mut s, &report.video_confusion, &pre);
    if let Some(first) = report.runs.first() {
        let _ = writeln!(
            s,
            "\n## Baseline object → pre-shape\n\n| object | pre-shape |\n|---|---|"
        );
        for (o, p) in &first.metrics.baseline.object_preshape {
            let _ = writeln!(s, "| {o} | {p} |");
        }
    }
    let _ = writeln!(
        s,
        "\n## Accuracy against time (Fig. 5)\n\nFrames labelled with a pre-shape only; \
         the `no_grasp` columns are the share of them answered `no_grasp` (an abstention, not \
         a wrong part).\n\n![accuracy against time](time_accuracy.png)\n\n| time (s) | \
         single-grasp (%) | multi-grasp (%) | single: no_grasp (%) | multi: no_grasp (%) |\n\
         |---|---|---|---|---|"
    );
    let (a, b) = (report.time_single.accuracy(), report.time_multi.accuracy());
    let (na, nb) = (
        report.time_single.no_grasp_share(),
        report.time_multi.no_grasp_share(),
    );
    let at = |v: &[Option<f64>], i: usize| pct(v.get(i).copied().flatten());
    for i in 0..a.len().max(b.len()) {
        let _ = writeln!(
            s,
            "| {:.2} | {} | {} | {} | {} |",
            i as f64 * report.time_bin_s,
            at(&a, i),
            at(&b, i),
            at(&na, i),
            at(&nb, i)
        );
    }
    let _ = writeln!(
        s,
        "\nRules: a frame's prediction is the argmax (ties: lowest class index). A video's \
         prediction is the majority vote over frames predicted as a pre-shape (no_grasp votes \
         are dropped); ties, including videos with no pre-shape vote, go to the tied pre-shape \
         with the highest summed probability, then the lowest class index. The baseline answers \
         each object's most frequent pre-shape among the evaluated videos (ties: lowest index). \
         Std is the population std over runs."
    );
    s
}

/// How the hand's decisions were taken (summed over runs), with the policy.
fn hand_section(s: &mut String, r: &Report) {
    let mut counts: BTreeMap<grasp_policy::OutcomeKind, usize> = BTreeMap::new();
    let mut times = Vec::new();
    for run in &r.runs {
        for (k, n) in &run.metrics.hand.outcomes {
            *counts.entry(*k).or_default() += n;
        }
        times.extend(run.metrics.hand.mean_decision_s);
    }
    if counts.is_empty() {
        return;
    }
    let listed: Vec<String> = counts
        .iter()
        .map(|(k, n)| format!("{} {n}", k.name()))
        .collect();
    let when = mean_std(&times)
        .map(|m| format!("; decided {:.2} s after the first frame on average", m.mean))
        .unwrap_or_default();
    let _ = writeln!(
        s,
        "\nThe hand's decisions, summed over runs: {}{when}.",
        listed.join(", ")
    );
    if let Some(p) = &r.policy {
        let fallback = p.fallback.map_or("none".to_string(), |f| f.to_string());
        let early = p
            .early_margin
            .map_or("off".to_string(), |m| format!("{m} votes"));
        let _ = writeln!(
            s,
            "Policy: window {} s, early decision {early}, at least {} votes, share {}, mean \
             probability {}, fallback {fallback}.",
            p.window_s, p.min_votes, p.min_share, p.min_confidence
        );
    }
}

/// The per-part section: each part of each multi-grasp object.
fn part_table(s: &mut String, r: &Report) {
    let _ = writeln!(
        s,
        "\n## Per-part accuracy of multi-grasp objects (%), mean ± std over runs\n"
    );
    if r.per_part.is_empty() {
        let _ = writeln!(
            s,
            "No multi-grasp object with recorded parts in this data (the authors' real layout \
             has no part annotation)."
        );
        return;
    }
    let _ = writeln!(
        s,
        "| object | part | pre-shape | videos | per-video | per-frame (pre-shape frames) |\n|---|---|---|---|---|---|"
    );
    for p in &r.per_part {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            p.object,
            p.part,
            p.preshape,
            p.videos,
            pct_ms(Some(&p.video_accuracy)),
            pct_ms(p.frame_accuracy.as_ref())
        );
    }
}

fn matrix(s: &mut String, m: &[Vec<u64>], names: &[&str]) {
    let _ = writeln!(s, "| | {} |", names.join(" | "));
    let _ = writeln!(s, "|---|{}", "---|".repeat(names.len()));
    for (name, row) in names.iter().zip(m) {
        let cells: Vec<String> = row.iter().map(u64::to_string).collect();
        let _ = writeln!(s, "| {name} | {} |", cells.join(" | "));
    }
}
