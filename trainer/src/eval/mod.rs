//! Evaluation: per-frame and per-video metrics, the perfect-object-classifier
//! baseline, accuracy against time, and the Markdown/JSON/PNG report.

pub mod choice;
pub mod files;
pub mod html;
pub mod metrics;
pub mod plots;
pub mod predict;
pub mod report;
pub mod row;
pub mod summary;

pub use files::write_report;
pub use metrics::{compute_metrics, Metrics, VideoPrediction};
pub use report::Report;
