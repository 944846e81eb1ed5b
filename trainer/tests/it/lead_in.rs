//! Gives a generated sequence a lead-in: its first frames do not see the
//! target, as at the start of a from_ground reach.

use std::path::{Path, PathBuf};

/// The `sequence.json` of the first sequence (in path order) of `root` that
/// shows `part`.
pub fn sequence_json(root: &Path, part: &str) -> PathBuf {
    let shows = |p: &PathBuf| {
        let rec: serde_json::Value = serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap();
        rec["plan"]["key"]["part"] == part
    };
    grasp_test_support::files_under(root)
        .into_iter()
        .filter(|p| p.ends_with("sequence.json"))
        .find(shows)
        .unwrap()
}

/// Points the wrist camera of the first `away` frames of `json` beside the
/// target (it sees the floor) and the rest straight down at it.
pub fn look_away_first(json: &Path, away: usize) {
    let mut rec: serde_json::Value = serde_json::from_slice(&std::fs::read(json).unwrap()).unwrap();
    let target = rec["plan"]["target"].clone();
    let t: Vec<f64> = serde_json::from_value(target).unwrap();
    for (i, f) in rec["plan"]["frames"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .enumerate()
    {
        let dx = if i < away { 5.0 } else { 0.0 };
        f["camera"] = serde_json::json!({
            "position": [t[0] + dx, t[1], t[2] + 1.0],
            "rotation_wxyz": [1.0, 0.0, 0.0, 0.0],
        });
    }
    std::fs::write(json, serde_json::to_vec(&rec).unwrap()).unwrap();
}
