//! Which model to ship: the one whose worst test set is best, judged by
//! what the hand would do. A model chosen on its own conditions can lose
//! most where it was never tuned (another renderer, real meshes, another
//! reach), so the choice looks at every test set of a by-condition summary
//! and ranks each model by its lowest accuracy of the hand's decision
//! (`hannes-run`'s policy on each video, mean over seeds); ties go to the
//! higher worst per-video vote, then to the higher mean of the hand's
//! decision over all sets, then to the model listed first. Only a model
//! whose head classifies frame by frame can ship, because the hand's loop
//! (`hannes-run`) runs nothing else; the others are ranked and marked.

use super::row::{conditions, models, Row};
use crate::error::SummaryError;
use grasp_model::heads::HeadKind;
use serde::Serialize;
use std::fmt::Write;

/// One model's standing: its worst test set by the hand's decision, its
/// worst per-video vote, and its means over all sets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Standing {
    pub model: String,
    /// The set where the hand's decision is least often right.
    pub worst_set: String,
    pub worst_hand_accuracy: f64,
    /// The lowest per-video (vote) accuracy over the sets, and its set.
    pub worst_vote_set: String,
    pub worst_vote_accuracy: f64,
    pub mean_hand_accuracy: f64,
    pub mean_vote_accuracy: f64,
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
    /// Ranks the models of a by-condition summary's rows; every model must
    /// have a report on every test set that any model has, so that all are
    /// judged on the same worlds.
    pub fn by_worst_set(rows: &[Row]) -> Result<Choice, SummaryError> {
        let sets = conditions(rows);
        let mut standings = Vec::new();
        for model in models(rows) {
            let mut hand = Vec::new();
            let mut vote = Vec::new();
            let mut head = String::new();
            for set in &sets {
                let Some(row) = rows.iter().find(|r| r.group_name() == (&model, set)) else {
                    let set = set.clone();
                    return Err(SummaryError::MissingSet { model, set });
                };
                hand.push((set, row.hand()?.mean));
                vote.push((set, row.video_accuracy.mean));
                head = row.head.clone();
            }
            let (worst_set, worst_hand_accuracy) = lowest(&hand);
            let (worst_vote_set, worst_vote_accuracy) = lowest(&vote);
            standings.push(Standing {
                model,
                worst_set: worst_set.clone(),
                worst_hand_accuracy,
                worst_vote_set: worst_vote_set.clone(),
                worst_vote_accuracy,
                mean_hand_accuracy: mean(&hand),
                mean_vote_accuracy: mean(&vote),
                head,
            });
        }
        // Stable: equal standings keep the order given.
        standings.sort_by(|a, b| {
            b.worst_hand_accuracy
                .total_cmp(&a.worst_hand_accuracy)
                .then(b.worst_vote_accuracy.total_cmp(&a.worst_vote_accuracy))
                .then(b.mean_hand_accuracy.total_cmp(&a.mean_hand_accuracy))
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
            "\n## The shipped model: the best worst test set by the hand's decision\n\n\
             | model | worst test set (hand) | the hand's decision there | worst per-video vote \
             | mean of the hand's decision | mean per-video vote |\n|---|---|---|---|---|---|\n",
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
                "| {}{mark} | {} | {:.1} | {:.1} ({}) | {:.1} | {:.1} |",
                st.model,
                st.worst_set,
                st.worst_hand_accuracy * 100.0,
                st.worst_vote_accuracy * 100.0,
                st.worst_vote_set,
                st.mean_hand_accuracy * 100.0,
                st.mean_vote_accuracy * 100.0
            );
        }
        s
    }
}

/// The lowest `(set, accuracy)`; the first of equals.
fn lowest(accuracies: &[(&String, f64)]) -> (String, f64) {
    let mut worst = accuracies[0];
    for &(set, a) in &accuracies[1..] {
        if a < worst.1 {
            worst = (set, a);
        }
    }
    (worst.0.clone(), worst.1)
}

fn mean(accuracies: &[(&String, f64)]) -> f64 {
    accuracies.iter().map(|(_, a)| a).sum::<f64>() / accuracies.len() as f64
}
