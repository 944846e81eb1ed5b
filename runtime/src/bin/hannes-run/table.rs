//! How predictions and votes print.

use grasp_schema::taxonomy::Class;
use runtime::approach::FramePrediction;

pub(crate) fn votes(votes: &[u32; Class::COUNT]) -> String {
    Class::ALL
        .iter()
        .map(|c| format!("{c} {}", votes[c.index()]))
        .collect::<Vec<_>>()
        .join(", ")
}

pub(crate) fn header() -> String {
    let classes: Vec<String> = Class::ALL.iter().map(|c| format!("{c:>8}")).collect();
    format!(
        "frame   time_s  {}  predicted  label     ms",
        classes.join("")
    )
}

pub(crate) fn row(prediction: &FramePrediction, truth: Option<Class>) -> String {
    let probs: Vec<String> = prediction
        .probabilities
        .iter()
        .map(|v| format!("{v:>8.3}"))
        .collect();
    let class = prediction
        .class
        .map_or("INVALID".to_string(), |c| c.to_string());
    let truth = truth.map_or("-".to_string(), |c| c.to_string());
    format!(
        "{:>5} {:>8.3}  {}  {:<9}  {:<8} {:>5.1}",
        prediction.index,
        prediction.time_s,
        probs.join(""),
        class,
        truth,
        prediction.inference_ms
    )
}
