//! A summary's rows: one report's headline numbers ([`Row`]), the entry
//! naming the report ([`Entry`]), and the models and test sets of a
//! by-condition table of rows. The summary and the choice of the model to
//! ship both read them; this file imports neither.

use super::metrics::{FrameWindow, MeanStd};
use super::report::{PartSummary, Report};
use crate::error::SummaryError;
use grasp_schema::plan::Condition;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    pub label: String,
    #[serde(default)]
    pub x: Option<f64>,
    /// `report.json` or the directory holding it.
    pub path: PathBuf,
}

impl Entry {
    /// Parses `LABEL[=X]:PATH` (the label holds no `:`, the path may).
    pub fn parse(spec: &str) -> Result<Entry, SummaryError> {
        let refuse = |reason: String| SummaryError::Entry {
            spec: spec.to_string(),
            reason,
        };
        let form = "expected LABEL[=X]:PATH, e.g. cycles-4=4:runs/q4/report";
        let (head, path) = spec
            .split_once(':')
            .ok_or_else(|| refuse(format!("no `:` ({form})")))?;
        let (label, x) = match head.split_once('=') {
            Some((l, x)) => {
                let v: f64 = x
                    .trim()
                    .parse()
                    .map_err(|e| refuse(format!("x value `{x}` is not a number ({form}): {e}")))?;
                (l, Some(v))
            }
            None => (head, None),
        };
        let e = Entry {
            label: label.trim().to_string(),
            x,
            path: PathBuf::from(path),
        };
        e.check().map_err(refuse)?;
        Ok(e)
    }

    /// What is wrong with the entry, if anything.
    pub(super) fn check(&self) -> Result<(), String> {
        if self.label.is_empty() {
            return Err("empty label".into());
        }
        if self.path.as_os_str().is_empty() {
            return Err("empty path".into());
        }
        if let Some(x) = self.x.filter(|x| !x.is_finite()) {
            return Err(format!("x value {x} is not finite"));
        }
        Ok(())
    }
}

/// One report's headline numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub label: String,
    pub x: Option<f64>,
    pub source: PathBuf,
    pub mode: String,
    pub backbone: String,
    pub head: String,
    pub dataset: PathBuf,
    pub sequences_per_pair: Option<usize>,
    pub train_sequences: Option<usize>,
    pub runs: usize,
    pub video_accuracy: MeanStd,
    /// `1 - video_accuracy`, with the same std.
    pub video_error: MeanStd,
    pub frame_accuracy: Option<MeanStd>,
    pub frame_accuracy_without_no_grasp: Option<MeanStd>,
    pub baseline_video_accuracy: Option<MeanStd>,
    /// Per-video accuracy on objects with one pre-shape and with several.
    #[serde(default)]
    pub video_accuracy_single: Option<MeanStd>,
    #[serde(default)]
    pub video_accuracy_multi: Option<MeanStd>,
    /// Per-part accuracy of the multi-grasp objects (empty for data without
    /// parts, or reports written before it existed).
    #[serde(default)]
    pub per_part: Vec<PartSummary>,
    /// The frames the report scored.
    #[serde(default)]
    pub window: FrameWindow,
    /// What the hand would be commanded (`hannes-run`'s policy), overall and
    /// by kind of object (None for reports written before it was scored).
    #[serde(default)]
    pub hand_accuracy: Option<MeanStd>,
    #[serde(default)]
    pub hand_accuracy_single: Option<MeanStd>,
    #[serde(default)]
    pub hand_accuracy_multi: Option<MeanStd>,
    /// Pre-shape frames right in the last second before contact.
    #[serde(default)]
    pub last_second_accuracy: Option<MeanStd>,
}

impl Row {
    pub fn load(entry: &Entry) -> Result<Row, SummaryError> {
        let file = if entry.path.is_dir() {
            entry.path.join("report.json")
        } else {
            entry.path.clone()
        };
        let label = || entry.label.clone();
        let text = std::fs::read_to_string(&file).map_err(|source| SummaryError::ReadReport {
            label: label(),
            path: file.clone(),
            source,
        })?;
        let r: Report = serde_json::from_str(&text).map_err(|e| SummaryError::NotAReport {
            label: label(),
            path: file.clone(),
            reason: e.to_string(),
        })?;
        let get = |k: &str| r.aggregate.get(k).copied();
        let video = get("video_accuracy").ok_or_else(|| SummaryError::NoRuns {
            label: label(),
            path: file.clone(),
        })?;
        Ok(Row {
            label: entry.label.clone(),
            x: entry.x,
            source: file,
            mode: r.mode,
            backbone: r.backbone,
            head: r.head,
            dataset: r.dataset,
            sequences_per_pair: r.sequences_per_pair,
            train_sequences: r.train_sequences,
            runs: video.n,
            video_accuracy: video,
            video_error: MeanStd {
                mean: 1.0 - video.mean,
                ..video
            },
            frame_accuracy: get("frame_accuracy"),
            frame_accuracy_without_no_grasp: get("frame_accuracy_without_no_grasp"),
            baseline_video_accuracy: get("baseline_video_accuracy"),
            video_accuracy_single: get("video_accuracy_single"),
            video_accuracy_multi: get("video_accuracy_multi"),
            per_part: r.per_part,
            window: r.window,
            hand_accuracy: get("hand_accuracy"),
            hand_accuracy_single: get("hand_accuracy_single"),
            hand_accuracy_multi: get("hand_accuracy_multi"),
            last_second_accuracy: get("last_second_accuracy"),
        })
    }

    /// The hand's decision's accuracy, or the error naming a report that
    /// predates it.
    pub fn hand(&self) -> Result<MeanStd, SummaryError> {
        self.hand_accuracy
            .ok_or_else(|| SummaryError::NoHandDecision {
                label: self.label.clone(),
                path: self.source.clone(),
            })
    }

    /// `(group, name)` of a `GROUP/NAME` label (the model and condition in
    /// the by-condition table, the series on the plot).
    pub fn group_name(&self) -> (&str, &str) {
        self.label.rsplit_once('/').unwrap_or(("", &self.label))
    }
}

/// The test sets (conditions) of `MODEL/CONDITION` rows in the paper's order, then unknown ones as they come.
pub fn conditions(rows: &[Row]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    let given: Vec<&str> = rows.iter().map(|r| r.group_name().1).collect();
    for c in Condition::ALL {
        if given.contains(&c.name()) {
            names.push(c.name().to_string());
        }
    }
    for g in given {
        if !names.iter().any(|n| n == g) {
            names.push(g.to_string());
        }
    }
    names
}

/// The models of `MODEL/CONDITION` rows in the order given.
pub fn models(rows: &[Row]) -> Vec<String> {
    let mut models: Vec<String> = Vec::new();
    for r in rows {
        let m = r.group_name().0;
        if !models.iter().any(|x| x == m) {
            models.push(m.to_string());
        }
    }
    models
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_parse_and_name_their_mistakes() {
        let e = Entry::parse("cycles-4=4.0:runs/q4/report/default").unwrap();
        assert_eq!(e.label, "cycles-4");
        assert_eq!(e.x, Some(4.0));
        assert_eq!(e.path, PathBuf::from("runs/q4/report/default"));
        let e = Entry::parse("fc/seated:C:\\runs\\seated").unwrap();
        assert_eq!((e.label.as_str(), e.x), ("fc/seated", None));
        assert_eq!(e.path, PathBuf::from("C:\\runs\\seated"));
        for bad in ["no-colon", "=3:p", "a=four:p", "a:", "a=inf:p"] {
            let err = format!("{:#}", Entry::parse(bad).unwrap_err());
            assert!(err.contains(bad), "{err}");
        }
    }
}
