//! Reading the plans `grasp-gen plan --out` writes: one JSON object per line.

use super::error::{PlanError, Result};
use grasp_schema::SequencePlan;
use std::path::Path;

/// Reads plans written by `grasp-gen plan --out`, naming the file and line on error.
pub fn read_jsonl(path: &Path) -> Result<Vec<SequencePlan>> {
    let text = std::fs::read_to_string(path).map_err(|source| PlanError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l).map_err(|source| PlanError::NotAPlan {
                path: path.to_path_buf(),
                line: i + 1,
                source,
            })
        })
        .collect()
}
