//! An evaluation's files: `report.json`, the plots, `videos.csv`,
//! `report.html` and `report.md`, each written from the [`Report`]. It
//! lives apart from `report.rs` because it writes the pages (`html`), and
//! the pages read the report: `report.rs` imports neither.

use super::report::{markdown, videos_csv, Report};
use super::{html, plots};
use crate::error::EvalError;
use std::path::Path;

/// Writes the report's files into `dir`.
pub fn write_report(report: &Report, dir: &Path) -> Result<(), EvalError> {
    std::fs::create_dir_all(dir).map_err(|source| EvalError::Create {
        path: dir.to_path_buf(),
        source,
    })?;
    grasp_support::atomic::write_atomic(
        &dir.join("report.json"),
        serde_json::to_string_pretty(report)?.as_bytes(),
    )?;
    let time_accuracy = plots::time_accuracy(&plots::TimeAccuracy {
        title: format!("Accuracy against time ({}, {})", report.mode, report.head),
        bin_s: report.time_bin_s,
        single: &report.time_single.accuracy(),
        multi: &report.time_multi.accuracy(),
        single_no_grasp: &report.time_single.no_grasp_share(),
        multi_no_grasp: &report.time_multi.no_grasp_share(),
    })?;
    grasp_support::atomic::write_atomic(&dir.join("time_accuracy.png"), &time_accuracy)?;
    let confusion = plots::confusion(&report.frame_confusion, &grasp_schema::Class::names())?;
    grasp_support::atomic::write_atomic(&dir.join("confusion.png"), &confusion)?;
    grasp_support::atomic::write_atomic(&dir.join("videos.csv"), videos_csv(report).as_bytes())?;
    html::write_report_html(report, dir)?;
    Ok(grasp_support::atomic::write_atomic(
        &dir.join("report.md"),
        markdown(report).as_bytes(),
    )?)
}
