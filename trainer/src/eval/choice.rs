//! Which model to ship: the one whose worst test set is best. A model
//! chosen on its own conditions can lose most where it was never tuned
//! (another renderer, real meshes, another reach), so the choice looks at
//! every test set of a by-condition summary and ranks each model by its
//! lowest per-video accuracy (mean over seeds); ties go to the higher
//! mean over all sets, then to the model listed first. Only a model whose
//! head classifies frame by frame can ship, because the hand's loop
//! (`hannes-run`) runs nothing else; the others are ranked and marked.

use super::summary::Summary;
use crate::error::SummaryError;
use grasp_model::heads::HeadKind;
use serde::Serialize;
use std::fmt::Write;

/// One model's standing: its worst test set and its mean over all sets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Standing {
    pub model: String,
    pub worst_set: String,
    pub worst_accuracy: f64,
    pub mean_accuracy: f64,
    /// The head of its reports (`fc`, `lstm`).
    pub head: String,
}

impl Standing {
    /// Whether the hand's loop can run it ([`HeadKind::classifies_frames`]).
    pub fn runs_on_hand(&self) -> bool {
        HeadKind::from_name(&self.head).is_some_and(HeadKind::classifies_frames)
    }
}

/// The choice and every model's standing, best first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Choice {
    pub shipped: String,
    pub standings: Vec<Standing>,
}

impl Choice {
    /// Ranks the summary's models; every model must have a report on every
    /// test set that any model has, so that all are judged on the same worlds.
    pub fn by_worst_set(summary: &Summary) -> Result<Choice, SummaryError> {
        let sets = summary.conditions();
        let mut standings = Vec::new();
        for model in summary.models() {
            let mut accuracies = Vec::new();
            let mut head = String::new();
            for set in &sets {
                let Some(row) = summary
                    .rows
                    .iter()
                    .find(|r| r.group_name() == (&model, set))
                else {
                    let set = set.clone();
                    return Err(SummaryError::MissingSet { model, set });
                };
                accuracies.push((set, row.video_accuracy.mean));
                head = row.head.clone();
            }
            let (worst_set, worst_accuracy) = accuracies
                .iter()
                .fold(None, |acc: Option<(&String, f64)>, &(s, a)| match acc {
                    Some((_, best)) if best <= a => acc,
                    _ => Some((s, a)),
                })
                .expect("a summary has at least one report");
            let mean_accuracy =
                accuracies.iter().map(|(_, a)| a).sum::<f64>() / accuracies.len() as f64;
            standings.push(Standing {
                model,
                worst_set: worst_set.clone(),
                worst_accuracy,
                mean_accuracy,
                head,
            });
        }
        // Stable: equal standings keep the order given.
        standings.sort_by(|a, b| {
            b.worst_accuracy
                .total_cmp(&a.worst_accuracy)
                .then(b.mean_accuracy.total_cmp(&a.mean_accuracy))
        });
        let Some(shipped) = standings.iter().find(|s| s.runs_on_hand()) else {
            let heads = standings
                .iter()
                .map(|s| format!("{} ({})", s.model, s.head));
            let heads = heads.collect::<Vec<_>>().join(", ");
            return Err(SummaryError::NothingShippable { heads });
        };
        Ok(Choice {
            shipped: shipped.model.clone(),
            standings,
        })
    }

    /// The Markdown section of summary.md.
    pub fn markdown(&self) -> String {
        let mut s = String::from(
            "\n## The shipped model: the best worst test set\n\n\
             | model | worst test set | its per-video accuracy | mean over the sets |\n|---|---|---|---|\n",
        );
        for st in &self.standings {
            let mark = if st.model == self.shipped {
                " (shipped)".to_string()
            } else if !st.runs_on_hand() {
                format!(
                    " (not shippable: its {} head does not run on the hand)",
                    st.head
                )
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "| {}{mark} | {} | {:.1} | {:.1} |",
                st.model,
                st.worst_set,
                st.worst_accuracy * 100.0,
                st.mean_accuracy * 100.0
            );
        }
        s
    }
}
