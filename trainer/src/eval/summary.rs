//! `grasp-train summarize`: several evaluation reports side by side.
//!
//! Each entry is a label, an optional numeric x (render samples, seconds per
//! frame, sequences per pair...) and a `report.json` written by
//! `grasp-train eval`. Outputs: a Markdown table of the headline numbers
//! (mean ± std over each report's seeds), the same as JSON, and, when
//! entries have an x, per-video error against x as a PNG. With
//! `by_condition`, labels are `MODEL/CONDITION` and the table has one row
//! per model and one column per test condition (the paper's Table 3).

pub use super::row::{Entry, Row};

use super::metrics::MeanStd;
use crate::error::SummaryError;
use serde::{Deserialize, Serialize};
use std::fmt::Write;
use std::path::Path;

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
            s.choice = Some(super::choice::Choice::by_worst_set(&s.rows)?);
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
        super::row::conditions(&self.rows)
    }

    /// Models in the order given.
    pub fn models(&self) -> Vec<String> {
        super::row::models(&self.rows)
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
