//! `grasp-train summarize`: several evaluation reports side by side.
//!
//! Each entry is a label, an optional numeric x (render samples, seconds per
//! frame, sequences per pair...) and a `report.json` written by
//! `grasp-train eval`. Outputs: a Markdown table of the headline numbers
//! (mean ± std over each report's seeds), the same as JSON, and, when
//! entries have an x, per-video error against x as a PNG. With
//! `by_condition`, labels are `MODEL/CONDITION` and the table has one row
//! per model and one column per test condition (the paper's Table 3).

use super::metrics::MeanStd;
use super::report::{PartSummary, Report};
use crate::error::SummaryError;
use grasp_schema::plan::Condition;
use serde::{Deserialize, Serialize};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// What to summarize: the command line's flags, or a TOML file of the same
/// fields with `[[report]]` tables.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SummarySpec {
    pub title: Option<String>,
    /// The x axis's name on the plot and in the table.
    pub x_label: Option<String>,
    pub log_x: bool,
    /// Labels are `MODEL/CONDITION`: one row per model, conditions as columns.
    pub by_condition: bool,
    /// With `by_condition`: choose the model to ship by its worst test set
    /// ([`super::choice`]); written to `shipped.txt` and the summary.
    pub ship_by_worst: bool,
    #[serde(rename = "report")]
    pub reports: Vec<Entry>,
}

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
    fn check(&self) -> Result<(), String> {
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

impl SummarySpec {
    /// Reads a TOML list; relative paths are taken from the current
    /// directory when they exist there, otherwise from the file's.
    pub fn from_toml_file(path: &Path) -> Result<SummarySpec, SummaryError> {
        let text = std::fs::read_to_string(path).map_err(|source| SummaryError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let mut spec: SummarySpec = toml::from_str(&text).map_err(|e| SummaryError::List {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        for (i, e) in spec.reports.iter_mut().enumerate() {
            e.check().map_err(|reason| SummaryError::ListEntry {
                path: path.to_path_buf(),
                index: i + 1,
                label: e.label.clone(),
                reason,
            })?;
            e.path = grasp_model::backbone::resolve(&e.path, dir);
        }
        Ok(spec)
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
    pub window: super::metrics::FrameWindow,
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

/// The summary: rows in the order given, and the spec they came from.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub spec: SummarySpec,
    pub rows: Vec<Row>,
    /// The model to ship, with `ship_by_worst`.
    pub choice: Option<super::choice::Choice>,
}

impl Summary {
    pub fn load(spec: SummarySpec) -> Result<Summary, SummaryError> {
        if spec.reports.is_empty() {
            return Err(SummaryError::Nothing);
        }
        let rows = spec
            .reports
            .iter()
            .map(Row::load)
            .collect::<Result<_, _>>()?;
        let mut s = Summary {
            spec,
            rows,
            choice: None,
        };
        if s.spec.by_condition {
            s.check_by_condition()?;
        }
        if s.spec.ship_by_worst {
            if !s.spec.by_condition {
                return Err(SummaryError::ShipNeedsConditions);
            }
            s.choice = Some(super::choice::Choice::by_worst_set(&s)?);
        }
        Ok(s)
    }

    fn check_by_condition(&self) -> Result<(), SummaryError> {
        let mut seen = std::collections::HashSet::new();
        for r in &self.rows {
            let label = r.label.clone();
            if !r.label.contains('/') {
                return Err(SummaryError::NotByCondition { label });
            }
            if !seen.insert(r.group_name()) {
                return Err(SummaryError::Twice { label });
            }
        }
        Ok(())
    }

    pub fn has_x(&self) -> bool {
        self.rows.iter().any(|r| r.x.is_some())
    }

    /// Writes `summary.md`, `summary.json` and, with x values, `error.png`.
    pub fn write(&self, dir: &Path) -> Result<(), SummaryError> {
        std::fs::create_dir_all(dir).map_err(|source| SummaryError::Create {
            path: dir.to_path_buf(),
            source,
        })?;
        if self.has_x() {
            let png = super::plots::error_against_x(&self.error_plot()?)?;
            grasp_support::atomic::write_atomic(&dir.join("error.png"), &png)?;
        }
        if let Some(choice) = &self.choice {
            let line = format!("{}\n", choice.shipped);
            grasp_support::atomic::write_atomic(&dir.join("shipped.txt"), line.as_bytes())?;
        }
        grasp_support::atomic::write_atomic(
            &dir.join("summary.json"),
            serde_json::to_string_pretty(self)?.as_bytes(),
        )?;
        Ok(grasp_support::atomic::write_atomic(
            &dir.join("summary.md"),
            self.markdown().as_bytes(),
        )?)
    }

    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let title = self
            .spec
            .title
            .as_deref()
            .unwrap_or("Summary of evaluations");
        let _ = writeln!(s, "# {title}\n");
        let _ = writeln!(
            s,
            "Percentages, mean ± std (population) over each report's runs (seeds). The hand's \
             decision is what hannes-run's policy commands on each video (grasp-policy; a \
             fallback counts by the pre-shape it sends, no command as wrong); the per-video \
             accuracy is the paper's vote over every frame.\n"
        );
        if self.spec.by_condition {
            self.condition_table(&mut s);
            if let Some(choice) = &self.choice {
                s.push_str(&choice.markdown());
            }
            self.condition_part_table(&mut s);
            let _ = writeln!(s, "\n## Every report\n");
        }
        self.table(&mut s);
        if !self.spec.by_condition {
            self.part_table(&mut s);
        }
        if self.has_x() {
            let _ = writeln!(
                s,
                "\n![per-video error against {}](error.png)",
                self.x_label()
            );
        }
        self.sources(&mut s);
        s
    }

    /// The plot of per-video error against x: one series per label group.
    fn error_plot(&self) -> Result<super::plots::ErrorAgainstX, SummaryError> {
        let mut series: Vec<super::plots::Series> = Vec::new();
        for r in &self.rows {
            let Some(x) = r.x else { continue };
            if self.spec.log_x && x <= 0.0 {
                let label = r.label.clone();
                return Err(SummaryError::LogAxis { label, x });
            }
            let group = r.group_name().0.to_string();
            let point = (x, r.video_error.mean * 100.0, r.video_error.std * 100.0);
            match series.iter_mut().find(|(g, _)| *g == group) {
                Some((_, v)) => v.push(point),
                None => series.push((group, vec![point])),
            }
        }
        for (_, v) in &mut series {
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        let title = self
            .spec
            .title
            .clone()
            .unwrap_or_else(|| format!("Per-video error against {}", self.x_label()));
        Ok(super::plots::ErrorAgainstX {
            title,
            x_label: self.x_label().to_string(),
            log_x: self.spec.log_x,
            series,
        })
    }

    pub fn x_label(&self) -> &str {
        self.spec.x_label.as_deref().unwrap_or("x")
    }

    fn table(&self, s: &mut String) {
        let x = self.has_x();
        let xh = if x {
            format!(" {} |", self.x_label())
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "| label |{xh} runs | the hand's decision | per-video accuracy | per-video error | per-frame accuracy | per-frame w/o no_grasp | last second | baseline | single-grasp videos | multi-grasp videos |"
        );
        let _ = writeln!(
            s,
            "|---|{}---|---|---|---|---|---|---|---|---|---|",
            if x { "---|" } else { "" }
        );
        for r in &self.rows {
            let xv = if x {
                format!(" {} |", r.x.map(|v| v.to_string()).unwrap_or("–".into()))
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "| {} |{xv} {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.label,
                r.runs,
                pct(r.hand_accuracy.as_ref()),
                pct(Some(&r.video_accuracy)),
                pct(Some(&r.video_error)),
                pct(r.frame_accuracy.as_ref()),
                pct(r.frame_accuracy_without_no_grasp.as_ref()),
                pct(r.last_second_accuracy.as_ref()),
                pct(r.baseline_video_accuracy.as_ref()),
                pct(r.video_accuracy_single.as_ref()),
                pct(r.video_accuracy_multi.as_ref()),
            );
        }
    }

    /// Conditions in the paper's order, then unknown ones as they come.
    pub fn conditions(&self) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        let given: Vec<&str> = self.rows.iter().map(|r| r.group_name().1).collect();
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

    /// Models in the order given.
    pub fn models(&self) -> Vec<String> {
        let mut models: Vec<String> = Vec::new();
        for r in &self.rows {
            let m = r.group_name().0;
            if !models.iter().any(|x| x == m) {
                models.push(m.to_string());
            }
        }
        models
    }

    fn condition_table(&self, s: &mut String) {
        type Metric = fn(&Row) -> Option<&MeanStd>;
        let tables: [(&str, Metric); 4] = [
            (
                "The hand's decision (what hannes-run's policy commands) by test set",
                |r| r.hand_accuracy.as_ref(),
            ),
            (
                "Per-video accuracy (the paper's vote) by test condition",
                |r| Some(&r.video_accuracy),
            ),
            (
                "Multi-grasp objects: the hand's decision by test set",
                |r| r.hand_accuracy_multi.as_ref(),
            ),
            (
                "Pre-shape frames right in the last second before contact",
                |r| r.last_second_accuracy.as_ref(),
            ),
        ];
        for (i, (title, metric)) in tables.into_iter().enumerate() {
            if i > 0 {
                s.push('\n');
            }
            self.condition_metric_table(s, title, metric);
        }
    }

    /// One table: a row per model, a column per test set, `metric`'s cells.
    fn condition_metric_table(
        &self,
        s: &mut String,
        title: &str,
        metric: fn(&Row) -> Option<&MeanStd>,
    ) {
        let conditions = self.conditions();
        let _ = writeln!(s, "## {title}\n\n| model | {} |", conditions.join(" | "));
        let _ = writeln!(s, "|---|{}", "---|".repeat(conditions.len()));
        for m in self.models() {
            let cells: Vec<String> = conditions
                .iter()
                .map(|c| {
                    let row = self.rows.iter().find(|r| r.group_name() == (&m, c));
                    pct(row.and_then(metric))
                })
                .collect();
            let _ = writeln!(s, "| {m} | {} |", cells.join(" | "));
        }
    }

    /// Every (object, part, pre-shape) of the multi-grasp objects in any
    /// row, sorted.
    pub fn parts(&self) -> Vec<(String, String, String)> {
        let mut parts: Vec<(String, String, String)> = self
            .rows
            .iter()
            .flat_map(|r| &r.per_part)
            .map(|p| (p.object.clone(), p.part.clone(), p.preshape.to_string()))
            .collect();
        parts.sort();
        parts.dedup();
        parts
    }

    /// Per-video accuracy of each part: one row per model and part, the
    /// conditions as columns.
    fn condition_part_table(&self, s: &mut String) {
        let parts = self.parts();
        if parts.is_empty() {
            return;
        }
        let conditions = self.conditions();
        let _ = writeln!(
            s,
            "\n## Per-part per-video accuracy of multi-grasp objects by test condition\n\n| model | object | part | pre-shape | {} |",
            conditions.join(" | ")
        );
        let _ = writeln!(s, "|---|---|---|---|{}", "---|".repeat(conditions.len()));
        for m in self.models() {
            for (object, part, preshape) in &parts {
                let cells: Vec<String> = conditions
                    .iter()
                    .map(|c| {
                        let row = self.rows.iter().find(|r| r.group_name() == (&m, c));
                        part_cell(row, object, part)
                    })
                    .collect();
                let _ = writeln!(
                    s,
                    "| {m} | {object} | {part} | {preshape} | {} |",
                    cells.join(" | ")
                );
            }
        }
    }

    /// Per-video accuracy of each part, the reports as columns.
    fn part_table(&self, s: &mut String) {
        let parts = self.parts();
        if parts.is_empty() {
            return;
        }
        let labels: Vec<&str> = self.rows.iter().map(|r| r.label.as_str()).collect();
        let _ = writeln!(
            s,
            "\n## Per-part per-video accuracy of multi-grasp objects\n\n| object | part | pre-shape | {} |",
            labels.join(" | ")
        );
        let _ = writeln!(s, "|---|---|---|{}", "---|".repeat(labels.len()));
        for (object, part, preshape) in &parts {
            let cells: Vec<String> = self
                .rows
                .iter()
                .map(|r| part_cell(Some(r), object, part))
                .collect();
            let _ = writeln!(
                s,
                "| {object} | {part} | {preshape} | {} |",
                cells.join(" | ")
            );
        }
    }

    fn sources(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "\n## Sources\n\n| label | report | mode | head | backbone | training set | test data | frames scored |\n|---|---|---|---|---|---|---|---|"
        );
        for r in &self.rows {
            let training = match (r.train_sequences, r.sequences_per_pair) {
                (Some(n), Some(k)) => format!("{n} sequences (≤ {k} per pair)"),
                (Some(n), None) => format!("{n} sequences"),
                _ => "–".into(),
            };
            let _ = writeln!(
                s,
                "| {} | `{}` | {} | {} | {} | {} | `{}` | {} |",
                r.label,
                r.source.display(),
                r.mode,
                r.head,
                if r.backbone.is_empty() {
                    "–"
                } else {
                    &r.backbone
                },
                training,
                r.dataset.display(),
                r.window.describe()
            );
        }
    }
}

/// A part's per-video accuracy in a row ("–" where the row lacks it).
fn part_cell(row: Option<&Row>, object: &str, part: &str) -> String {
    let p = row.and_then(|r| {
        r.per_part
            .iter()
            .find(|p| p.object == object && p.part == part)
    });
    pct(p.map(|p| &p.video_accuracy))
}

fn pct(m: Option<&MeanStd>) -> String {
    m.map(|m| format!("{:.1} ± {:.1}", m.mean * 100.0, m.std * 100.0))
        .unwrap_or_else(|| "–".into())
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
