//! Metrics over per-frame class probabilities of whole videos.
//!
//! Rules (all documented in docs/trainer.md):
//! - frame prediction: the argmax over the five classes, ties to the lowest
//!   class index;
//! - per-frame accuracy "with no_grasp" counts every frame; "without" counts
//!   only frames labelled with a pre-shape (predicting `no_grasp` there is an
//!   error);
//! - per-video prediction (the paper's headline metric): majority vote over
//!   the frames whose prediction is a pre-shape (`no_grasp` votes are
//!   dropped). Ties, including a video with no pre-shape vote at all, go to
//!   the tied pre-shape with the highest probability summed over all frames,
//!   then to the lowest class index;
//! - the hand's decision: what `hannes-run`'s policy (`grasp-policy`, the
//!   report's settings) commands on the video's frames with their own time
//!   stamps, the trigger at the first scored frame: right when it names the
//!   video's pre-shape; a fallback counts by the pre-shape it sends, no
//!   command or an abort as wrong;
//! - accuracy against time: for every time bin, the fraction of the frames
//!   labelled with a pre-shape whose prediction equals it, separately for
//!   videos of single-grasp and multi-grasp objects (the paper's Fig. 5);
//!   the share of those frames answered `no_grasp` (an abstention, not a
//!   wrong part) is counted apart;
//! - the last second: the accuracy of the pre-shape frames in the second
//!   before the final `no_grasp` segment (contact), where the part must be
//!   read up close;
//! - baseline: a perfect object classifier that always answers the object's
//!   most frequent pre-shape among the evaluated videos (ties to the lowest
//!   class index);
//! - per-part accuracy: per-video accuracy of each part of each multi-grasp
//!   object, for data that records parts (the generator's); the per-frame
//!   accuracy of the part's pre-shape frames comes with it.
//!
//! A [`FrameWindow`] restricts every metric to the frames of a time window
//! (videos with no frame in it are left out and counted).

use crate::error::ConfigError;
use grasp_policy::{decide_recorded, OutcomeKind, PolicyConfig};
use grasp_schema::taxonomy::{Class, Preshape};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Predictions and ground truth of one video.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VideoPrediction {
    pub id: String,
    pub object: String,
    /// The object part, when the data records it (`sequence.json`).
    #[serde(default)]
    pub part: Option<String>,
    pub preshape: Preshape,
    /// Whether the object has several pre-shapes in the evaluated data.
    pub multi_grasp: bool,
    pub labels: Vec<Class>,
    pub probs: Vec<[f32; Class::COUNT]>,
    pub times_s: Vec<f64>,
}

/// The predicted class of a frame: argmax, ties to the lowest index.
pub fn frame_class(probs: &[f32; Class::COUNT]) -> usize {
    let mut best = 0;
    for class in 1..Class::COUNT {
        if probs[class] > probs[best] {
            best = class;
        }
    }
    best
}

/// The video's pre-shape by majority vote (see the module docs for ties).
pub fn video_class(probs: &[[f32; Class::COUNT]]) -> usize {
    // The pre-shape classes come first; no_grasp (the last) never wins.
    const PRESHAPES: usize = Preshape::ALL.len();
    let mut votes = [0usize; PRESHAPES];
    let mut mass = [0f64; PRESHAPES];
    for p in probs {
        let c = frame_class(p);
        if c < PRESHAPES {
            votes[c] += 1;
        }
        for k in 0..PRESHAPES {
            mass[k] += f64::from(p[k]);
        }
    }
    let top = *votes.iter().max().unwrap_or(&0);
    let mut best: Option<usize> = None;
    for c in 0..PRESHAPES {
        if votes[c] == top && best.is_none_or(|b| mass[c] > mass[b]) {
            best = Some(c);
        }
    }
    best.unwrap_or(0)
}

/// One video's outcome: what it was and what the vote said.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VideoOutcome {
    pub id: String,
    pub object: String,
    #[serde(default)]
    pub part: Option<String>,
    pub truth: Preshape,
    /// The majority vote.
    pub vote: Preshape,
    /// Frames scored.
    pub frames: usize,
    /// What the hand would be commanded (None in reports written before
    /// the hand's decision was scored).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hand: Option<HandDecision>,
}

impl VideoOutcome {
    pub fn of(v: &VideoPrediction, policy: &PolicyConfig) -> VideoOutcome {
        VideoOutcome {
            id: v.id.clone(),
            object: v.object.clone(),
            part: v.part.clone(),
            truth: v.preshape,
            vote: Preshape::ALL[video_class(&v.probs)],
            frames: v.probs.len(),
            hand: Some(HandDecision::of(v, policy)),
        }
    }
}

/// The decision `hannes-run`'s policy takes on a video.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandDecision {
    /// The pre-shape commanded; None: nothing.
    pub preshape: Option<Preshape>,
    pub how: OutcomeKind,
    /// Why the vote was not trusted (fallback, no command) or the approach
    /// aborted, in words.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub why: Option<String>,
    /// Frame time of the last frame the policy read, seconds after the
    /// first scored frame.
    pub at_s: Option<f64>,
}

impl HandDecision {
    pub fn of(v: &VideoPrediction, policy: &PolicyConfig) -> HandDecision {
        let frames = (0..v.probs.len()).map(|i| (v.time_s(i), v.probs[i]));
        let d = decide_recorded(policy, frames);
        let outcome = &d.decision.outcome;
        let why = match outcome {
            grasp_policy::Outcome::Fallback { why, .. }
            | grasp_policy::Outcome::NoCommand { why } => Some(why.to_string()),
            grasp_policy::Outcome::Aborted { error } => Some(error.clone()),
            _ => None,
        };
        HandDecision {
            preshape: outcome.preshape(),
            how: outcome.kind(),
            why,
            at_s: d.at_s,
        }
    }

    pub fn is_right(&self, truth: Preshape) -> bool {
        self.preshape == Some(truth)
    }
}

impl VideoPrediction {
    /// Frame `i`'s time, seconds (0 where the data has none).
    pub fn time_s(&self, i: usize) -> f64 {
        self.times_s.get(i).copied().unwrap_or(0.0)
    }
}

/// The hand's decisions over a set of videos.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct HandMetrics {
    pub accuracy: f64,
    pub accuracy_single: Option<f64>,
    pub accuracy_multi: Option<f64>,
    /// Videos by how the decision was taken.
    pub outcomes: BTreeMap<OutcomeKind, usize>,
    /// Mean frame time of the decision, seconds after the first frame.
    pub mean_decision_s: Option<f64>,
}

/// `outcomes`: per video, whether its object is multi-grasp, the decision,
/// and whether it is right.
fn hand_metrics(outcomes: &[(bool, HandDecision, bool)]) -> HandMetrics {
    let mut h = HandMetrics::default();
    let (mut ok, mut s, mut m) = (0, [0usize; 2], [0usize; 2]);
    let mut times = Vec::new();
    for (multi, d, right) in outcomes {
        ok += usize::from(*right);
        let group = if *multi { &mut m } else { &mut s };
        group[0] += 1;
        group[1] += usize::from(*right);
        *h.outcomes.entry(d.how).or_default() += 1;
        times.extend(d.at_s);
    }
    h.accuracy = ratio(ok, outcomes.len());
    h.accuracy_single = opt_ratio(s[1], s[0]);
    h.accuracy_multi = opt_ratio(m[1], m[0]);
    h.mean_decision_s = (!times.is_empty()).then(|| times.iter().sum::<f64>() / times.len() as f64);
    h
}

/// Accuracy against time for one group of videos: per bin, the frames
/// labelled with a pre-shape, those predicted right, and those answered
/// `no_grasp`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Curve {
    pub correct: Vec<u64>,
    pub total: Vec<u64>,
    #[serde(default)]
    pub no_grasp: Vec<u64>,
}

impl Curve {
    fn add(&mut self, bin: usize, predicted: usize, truth: usize) {
        self.grow(bin + 1);
        self.total[bin] += 1;
        self.correct[bin] += u64::from(predicted == truth);
        self.no_grasp[bin] += u64::from(predicted == Class::NoGrasp.index());
    }

    fn grow(&mut self, bins: usize) {
        for v in [&mut self.total, &mut self.correct, &mut self.no_grasp] {
            if v.len() < bins {
                v.resize(bins, 0);
            }
        }
    }

    /// Adds another curve's counts bin by bin.
    pub fn merge(&mut self, other: &Curve) {
        self.grow(other.total.len());
        for (i, t) in other.total.iter().enumerate() {
            self.total[i] += t;
            self.correct[i] += other.correct.get(i).copied().unwrap_or(0);
            self.no_grasp[i] += other.no_grasp.get(i).copied().unwrap_or(0);
        }
    }

    /// The share of each bin's pre-shape frames answered `no_grasp`.
    pub fn no_grasp_share(&self) -> Vec<Option<f64>> {
        self.total
            .iter()
            .enumerate()
            .map(|(i, t)| {
                (*t > 0).then(|| self.no_grasp.get(i).copied().unwrap_or(0) as f64 / *t as f64)
            })
            .collect()
    }

    pub fn accuracy(&self) -> Vec<Option<f64>> {
        self.correct
            .iter()
            .zip(&self.total)
            .map(|(c, t)| (*t > 0).then(|| *c as f64 / *t as f64))
            .collect()
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TimeCurves {
    pub bin_s: f64,
    pub single: Curve,
    pub multi: Curve,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Baseline {
    /// The pre-shape the perfect object classifier answers for each object.
    pub object_preshape: BTreeMap<String, Preshape>,
    pub video_accuracy: f64,
    pub video_accuracy_single: Option<f64>,
    pub video_accuracy_multi: Option<f64>,
}

/// Per-video accuracy of one part of a multi-grasp object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartAccuracy {
    pub object: String,
    pub part: String,
    pub preshape: Preshape,
    pub videos: usize,
    pub correct_videos: usize,
    pub video_accuracy: f64,
    /// Frames labelled with the pre-shape, and the fraction predicted right.
    pub grasp_frames: usize,
    pub frame_accuracy: Option<f64>,
}

/// How an evaluation scores its videos: which frames, and the policy the
/// hand's decision is taken with (`hannes-run`'s defaults unless given).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scoring {
    pub window: FrameWindow,
    pub policy: PolicyConfig,
}

/// Which frames are scored, by time since the start of the video. `from_s`
/// and `to_s` bound it absolutely; `before_tail_s` keeps the last seconds
/// before the final `no_grasp` segment (the whole tail-less video's end).
/// All given bounds apply together; none scores every frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameWindow {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before_tail_s: Option<f64>,
}

impl FrameWindow {
    pub fn is_all(&self) -> bool {
        *self == FrameWindow::default()
    }

    /// A readable form, e.g. "1.00 s to 2.50 s".
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some(f) = self.from_s {
            parts.push(format!("from {f:.2} s"));
        }
        if let Some(t) = self.to_s {
            parts.push(format!("before {t:.2} s"));
        }
        if let Some(k) = self.before_tail_s {
            parts.push(format!("the last {k:.2} s before the no_grasp tail"));
        }
        if parts.is_empty() {
            "every frame".into()
        } else {
            parts.join(", ")
        }
    }

    /// Checks the bounds.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (name, v) in [
            ("--from-s", self.from_s),
            ("--to-s", self.to_s),
            ("--before-tail-s", self.before_tail_s),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                let reason = format!("{name} must be a time >= 0 seconds, got {v}");
                return Err(ConfigError::invalid(name, reason));
            }
        }
        if let (Some(a), Some(b)) = (self.from_s, self.to_s) {
            if a >= b {
                let reason = format!("--from-s ({a}) must be before --to-s ({b})");
                return Err(ConfigError::invalid("--from-s", reason));
            }
        }
        Ok(())
    }

    /// Whether frame `i` of `v` is scored.
    fn keeps(&self, v: &VideoPrediction, i: usize, tail_start: f64) -> bool {
        let t = v.times_s.get(i).copied().unwrap_or(0.0);
        self.from_s.is_none_or(|f| t >= f - 1e-9)
            && self.to_s.is_none_or(|e| t < e - 1e-9)
            && self
                .before_tail_s
                .is_none_or(|k| t < tail_start - 1e-9 && t >= tail_start - k - 1e-9)
    }

    /// `v` restricted to the window (None when no frame is left).
    pub fn apply(&self, v: &VideoPrediction) -> Option<VideoPrediction> {
        if self.is_all() {
            return Some(v.clone());
        }
        let tail_start = tail_start(v);
        let keep: Vec<usize> = (0..v.labels.len().min(v.probs.len()))
            .filter(|&i| self.keeps(v, i, tail_start))
            .collect();
        if keep.is_empty() {
            return None;
        }
        let pick = |i: &usize| v.times_s.get(*i).copied().unwrap_or(0.0);
        Some(VideoPrediction {
            labels: keep.iter().map(|&i| v.labels[i]).collect(),
            probs: keep.iter().map(|&i| v.probs[i]).collect(),
            times_s: keep.iter().map(pick).collect(),
            ..v.clone()
        })
    }
}

/// Time of the first frame of the final run of `no_grasp` labels; without
/// one, one frame interval after the last frame.
fn tail_start(v: &VideoPrediction) -> f64 {
    let n = v.labels.len().min(v.times_s.len());
    let mut first = n;
    while first > 0 && v.labels[first - 1] == Class::NoGrasp {
        first -= 1;
    }
    if first < n {
        return v.times_s[first];
    }
    match (
        n,
        v.times_s.get(n.wrapping_sub(1)),
        v.times_s.get(n.wrapping_sub(2)),
    ) {
        (0, _, _) => 0.0,
        (_, Some(last), Some(prev)) => last + (last - prev),
        (_, Some(last), None) => last + 1e-6,
        _ => 0.0,
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub frames: usize,
    pub frame_accuracy: f64,
    pub grasp_frames: usize,
    pub frame_accuracy_without_no_grasp: f64,
    pub videos: usize,
    pub video_accuracy: f64,
    pub single_grasp_videos: usize,
    pub video_accuracy_single: Option<f64>,
    pub multi_grasp_videos: usize,
    pub video_accuracy_multi: Option<f64>,
    /// Rows: true class, columns: predicted class (5 classes).
    pub frame_confusion: Vec<Vec<u64>>,
    /// Rows: true pre-shape, columns: voted pre-shape (4 pre-shapes).
    pub video_confusion: Vec<Vec<u64>>,
    pub baseline: Baseline,
    pub time: TimeCurves,
    /// Per-video accuracy of each part of the multi-grasp objects (empty
    /// when the data records no parts).
    #[serde(default)]
    pub per_part: Vec<PartAccuracy>,
    /// What the hand would be commanded (see the module docs).
    #[serde(default)]
    pub hand: HandMetrics,
    /// Pre-shape frames in the last second before contact, and the share
    /// predicted right.
    #[serde(default)]
    pub last_second_frames: usize,
    #[serde(default)]
    pub last_second_accuracy: Option<f64>,
}

/// How long before contact (the final `no_grasp` segment) the last-second
/// accuracy looks.
pub const LAST_SECOND_S: f64 = 1.0;

fn ratio(num: usize, den: usize) -> f64 {
    if den == 0 {
        0.0
    } else {
        num as f64 / den as f64
    }
}

fn opt_ratio(num: usize, den: usize) -> Option<f64> {
    (den > 0).then(|| num as f64 / den as f64)
}

pub fn compute_metrics(videos: &[VideoPrediction], bin_s: f64, policy: &PolicyConfig) -> Metrics {
    let mut m = Metrics {
        frame_confusion: vec![vec![0; Class::COUNT]; Class::COUNT],
        video_confusion: vec![vec![0; 4]; 4],
        time: TimeCurves {
            bin_s,
            ..Default::default()
        },
        ..Default::default()
    };
    let (mut frame_ok, mut grasp_ok, mut video_ok) = (0, 0, 0);
    let (mut single_ok, mut multi_ok) = (0, 0);
    let (mut last_n, mut last_ok) = (0, 0);
    let mut decisions = Vec::with_capacity(videos.len());
    for v in videos {
        let truth = Class::from(v.preshape).index();
        let contact = tail_start(v);
        for (i, (p, label)) in v.probs.iter().zip(&v.labels).enumerate() {
            let c = frame_class(p);
            m.frames += 1;
            m.frame_confusion[label.index()][c] += 1;
            frame_ok += usize::from(c == label.index());
            if *label == Class::NoGrasp {
                continue;
            }
            m.grasp_frames += 1;
            grasp_ok += usize::from(c == label.index());
            let t = v.time_s(i);
            if t >= contact - LAST_SECOND_S - 1e-9 {
                last_n += 1;
                last_ok += usize::from(c == label.index());
            }
            let bin = (t / bin_s + 1e-9).floor().max(0.0) as usize;
            let curve = if v.multi_grasp {
                &mut m.time.multi
            } else {
                &mut m.time.single
            };
            curve.add(bin, c, label.index());
        }
        let hand = HandDecision::of(v, policy);
        let right = hand.is_right(v.preshape);
        decisions.push((v.multi_grasp, hand, right));
        let voted = video_class(&v.probs);
        m.video_confusion[truth][voted] += 1;
        m.videos += 1;
        let ok = voted == truth;
        video_ok += usize::from(ok);
        if v.multi_grasp {
            m.multi_grasp_videos += 1;
            multi_ok += usize::from(ok);
        } else {
            m.single_grasp_videos += 1;
            single_ok += usize::from(ok);
        }
    }
    m.frame_accuracy = ratio(frame_ok, m.frames);
    m.frame_accuracy_without_no_grasp = ratio(grasp_ok, m.grasp_frames);
    m.video_accuracy = ratio(video_ok, m.videos);
    m.video_accuracy_single = opt_ratio(single_ok, m.single_grasp_videos);
    m.video_accuracy_multi = opt_ratio(multi_ok, m.multi_grasp_videos);
    m.baseline = baseline(videos);
    m.per_part = per_part(videos);
    m.hand = hand_metrics(&decisions);
    m.last_second_frames = last_n;
    m.last_second_accuracy = opt_ratio(last_ok, last_n);
    m
}

/// Per-part accuracy of the multi-grasp objects' videos that record a part,
/// by (object, part).
pub fn per_part(videos: &[VideoPrediction]) -> Vec<PartAccuracy> {
    // (object, part) -> (pre-shape, videos, right videos, frames, right frames)
    let mut acc: BTreeMap<(&str, &str), (Preshape, [usize; 4])> = BTreeMap::new();
    for v in videos.iter().filter(|v| v.multi_grasp) {
        let Some(part) = v.part.as_deref() else {
            continue;
        };
        let (_, n) = acc.entry((&v.object, part)).or_insert((v.preshape, [0; 4]));
        n[0] += 1;
        n[1] += usize::from(video_class(&v.probs) == Class::from(v.preshape).index());
        for (p, l) in v.probs.iter().zip(&v.labels) {
            if *l != Class::NoGrasp {
                n[2] += 1;
                n[3] += usize::from(frame_class(p) == l.index());
            }
        }
    }
    acc.into_iter()
        .map(|((object, part), (preshape, n))| PartAccuracy {
            object: object.to_string(),
            part: part.to_string(),
            preshape,
            videos: n[0],
            correct_videos: n[1],
            video_accuracy: ratio(n[1], n[0]),
            grasp_frames: n[2],
            frame_accuracy: opt_ratio(n[3], n[2]),
        })
        .collect()
}

/// The perfect object classifier answering each object's most frequent
/// pre-shape.
pub fn baseline(videos: &[VideoPrediction]) -> Baseline {
    let mut counts: BTreeMap<&str, [usize; 4]> = BTreeMap::new();
    for v in videos {
        counts.entry(&v.object).or_default()[Class::from(v.preshape).index()] += 1;
    }
    let object_preshape: BTreeMap<String, Preshape> = counts
        .iter()
        .map(|(o, c)| {
            let mut best = 0;
            for k in 1..4 {
                if c[k] > c[best] {
                    best = k;
                }
            }
            (o.to_string(), Preshape::ALL[best])
        })
        .collect();
    let (mut ok, mut s_ok, mut s_n, mut m_ok, mut m_n) = (0, 0, 0, 0, 0);
    for v in videos {
        let hit = object_preshape[&v.object] == v.preshape;
        ok += usize::from(hit);
        if v.multi_grasp {
            m_n += 1;
            m_ok += usize::from(hit);
        } else {
            s_n += 1;
            s_ok += usize::from(hit);
        }
    }
    Baseline {
        object_preshape,
        video_accuracy: ratio(ok, videos.len()),
        video_accuracy_single: opt_ratio(s_ok, s_n),
        video_accuracy_multi: opt_ratio(m_ok, m_n),
    }
}

/// Mean and population standard deviation (numpy's default, as the paper's
/// "± std over runs").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    pub mean: f64,
    pub std: f64,
    pub n: usize,
}

pub fn mean_std(values: &[f64]) -> Option<MeanStd> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    Some(MeanStd {
        mean,
        std: var.sqrt(),
        n: values.len(),
    })
}

/// The headline scalars of a run, by name, for aggregation over seeds.
pub fn scalars(metrics: &Metrics) -> Vec<(&'static str, Option<f64>)> {
    vec![
        ("video_accuracy", Some(metrics.video_accuracy)),
        ("video_accuracy_single", metrics.video_accuracy_single),
        ("video_accuracy_multi", metrics.video_accuracy_multi),
        ("frame_accuracy", Some(metrics.frame_accuracy)),
        (
            "frame_accuracy_without_no_grasp",
            Some(metrics.frame_accuracy_without_no_grasp),
        ),
        (
            "baseline_video_accuracy",
            Some(metrics.baseline.video_accuracy),
        ),
        ("hand_accuracy", Some(metrics.hand.accuracy)),
        ("hand_accuracy_single", metrics.hand.accuracy_single),
        ("hand_accuracy_multi", metrics.hand.accuracy_multi),
        ("last_second_accuracy", metrics.last_second_accuracy),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ties_go_to_the_lowest_index() {
        assert_eq!(frame_class(&[0.2, 0.4, 0.4, 0.0, 0.0]), 1);
        assert_eq!(frame_class(&[0.0, 0.0, 0.0, 0.0, 1.0]), 4);
    }

    #[test]
    fn video_vote_ignores_no_grasp_and_breaks_ties_by_mass() {
        let ng = [0.0, 0.0, 0.0, 0.1, 0.9];
        let a = [0.6, 0.4, 0.0, 0.0, 0.0];
        let b = [0.0, 0.9, 0.1, 0.0, 0.0];
        // Two no_grasp frames, one vote each for power and lateral: tie;
        // lateral's summed probability 1.3 beats power's 0.6.
        assert_eq!(video_class(&[ng, ng, a, b]), 1);
        // Only no_grasp predictions: the pre-shape with the most mass
        // (pinch3, 0.2).
        assert_eq!(video_class(&[ng, ng]), 3);
        // Equal votes and equal mass: lowest index.
        let x = [0.6, 0.0, 0.4, 0.0, 0.0];
        let y = [0.4, 0.0, 0.6, 0.0, 0.0];
        assert_eq!(video_class(&[y, x]), 0);
    }
}
