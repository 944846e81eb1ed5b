//! The decision policy of the paper's demo: classify the frames of the
//! approach window, take the majority vote over the pre-shape classes
//! (`no_grasp` excluded), optionally decide early once the vote is decisive,
//! and fall back to a safe pre-shape when the vote is weak.
//!
//! A model output that is not a probability vector (NaN, Inf, out of range)
//! never reaches the vote: it aborts the approach (default) or is skipped.

use crate::probabilities::{InvalidOutput, Probabilities};
use crate::setting::{ensure, InvalidSetting};
use grasp_schema::taxonomy::{Class, Preshape};
use serde::{Deserialize, Serialize};
use std::fmt;

/// What to do with a frame whose model output is invalid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OnInvalid {
    /// End the approach without commanding the hand.
    Abort,
    /// Leave the frame out of the vote and go on.
    Skip,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PolicyConfig {
    /// Length of the approach window after the trigger, in seconds of
    /// frame time.
    pub window_s: f64,
    /// Decide before the window ends once the leader is this many votes
    /// ahead of the runner-up (and the confidence checks pass).
    pub early_margin: Option<u32>,
    /// Fewer pre-shape votes than this is low confidence.
    pub min_votes: u32,
    /// Minimum share of the pre-shape votes the winner must get.
    pub min_share: f64,
    /// Minimum mean probability of the winning class over its votes.
    pub min_confidence: f64,
    /// Pre-shape sent on low confidence; `None` sends nothing.
    pub fallback: Option<Preshape>,
    pub on_invalid: OnInvalid,
    /// A decision older than this is never sent: the pre-shape must be
    /// acknowledged within it (the closure within it of its trigger). The
    /// age counts from the moment the vote is settled, not from the capture
    /// of the frames voted on, so a slow source (a recording at 2.5
    /// frames/s) needs no allowance for its frame interval.
    pub max_decision_age_ms: u64,
}

/// Default age limit of a decision. The paper's approaches last about 2 s
/// and its recordings end with 0.5 s of contact: a pre-shape decided at the
/// end of the window has about half a second to be executed before the hand
/// reaches the object, and the fingers need part of it to move. 300 ms
/// leaves them the rest. A healthy link acknowledges in one round trip (2.3
/// ms of wire time at 115200 baud), over a hundred times less, and 300 ms
/// still covers the first transmission and two retransmissions at the
/// default 100 ms ACK timeout. It bounds what the host and the link add
/// after the decision; how old the newest frame is at the decision (up to
/// one frame interval) is part of the window, not of this budget.
pub const DEFAULT_MAX_DECISION_AGE_MS: u64 = 300;

impl Default for PolicyConfig {
    fn default() -> Self {
        PolicyConfig {
            window_s: 2.0,
            early_margin: None,
            min_votes: 3,
            min_share: 0.5,
            min_confidence: 0.5,
            fallback: Some(Preshape::Power),
            on_invalid: OnInvalid::Abort,
            max_decision_age_ms: DEFAULT_MAX_DECISION_AGE_MS,
        }
    }
}

/// A number as a message shows it: `1e308`, not its 309 digits.
fn num(x: f64) -> String {
    let a = x.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e9).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// The longest approach window accepted, in seconds (an hour; a window is
/// seconds long, and a larger one cannot be a time span).
pub const MAX_WINDOW_S: f64 = 3600.0;

impl PolicyConfig {
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        ensure(
            self.window_s.is_finite() && self.window_s > 0.0 && self.window_s <= MAX_WINDOW_S,
            "policy.window_s",
            || {
                format!(
                    "must be a positive number of seconds, at most {MAX_WINDOW_S}, got {}",
                    num(self.window_s)
                )
            },
        )?;
        ensure(
            (0.0..=1.0).contains(&self.min_share),
            "policy.min_share",
            || format!("must be in [0, 1], got {}", num(self.min_share)),
        )?;
        ensure(
            (0.0..=1.0).contains(&self.min_confidence),
            "policy.min_confidence",
            || format!("must be in [0, 1], got {}", num(self.min_confidence)),
        )?;
        ensure(self.early_margin != Some(0), "policy.early_margin", || {
            "must be at least 1 vote".into()
        })?;
        ensure(
            (1..=60_000).contains(&self.max_decision_age_ms),
            "policy.max_decision_age_ms",
            || format!("must be in [1, 60000], got {}", self.max_decision_age_ms),
        )
    }

    /// Whether a frame taken `since_trigger_s` seconds after the trigger
    /// (frame time) belongs to the approach window. The one rule of the
    /// live loop and of a recorded approach.
    pub fn in_window(&self, since_trigger_s: f64) -> bool {
        since_trigger_s < self.window_s
    }

    /// [`PolicyConfig::max_decision_age_ms`] as a duration.
    pub fn max_decision_age(&self) -> std::time::Duration {
        std::time::Duration::from_millis(self.max_decision_age_ms)
    }
}

/// Why the vote was judged too weak to trust.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LowConfidence {
    NoVotes,
    TooFewVotes { votes: u32, min: u32 },
    Tie { between: Vec<Preshape> },
    Share { share: f64, min: f64 },
    Confidence { mean: f64, min: f64 },
}

impl fmt::Display for LowConfidence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LowConfidence::NoVotes => write!(f, "every frame was no_grasp"),
            LowConfidence::TooFewVotes { votes, min } => {
                write!(f, "{votes} pre-shape votes, fewer than {min}")
            }
            LowConfidence::Tie { between } => {
                let names: Vec<_> = between.iter().map(|p| p.name()).collect();
                write!(f, "tie between {}", names.join(" and "))
            }
            LowConfidence::Share { share, min } => {
                write!(f, "winner has {share:.2} of the votes, below {min:.2}")
            }
            LowConfidence::Confidence { mean, min } => {
                write!(f, "mean winner probability {mean:.2} below {min:.2}")
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "how", rename_all = "snake_case")]
pub enum Outcome {
    /// The window's majority.
    Majority { preshape: Preshape },
    /// The vote became decisive before the window ended.
    Early { preshape: Preshape },
    /// Low confidence: the configured safe pre-shape.
    Fallback {
        preshape: Preshape,
        why: LowConfidence,
    },
    /// Low confidence and no fallback configured: nothing is sent.
    NoCommand { why: LowConfidence },
    /// The approach ended without actuation.
    Aborted { error: String },
    /// A stop was requested (a signal) before the vote was settled:
    /// nothing is sent.
    Stopped,
}

/// How an approach's decision was taken, without its evidence: what
/// reports count (fallbacks, approaches with no command).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutcomeKind {
    Majority,
    Early,
    Fallback,
    NoCommand,
    Aborted,
    Stopped,
}

impl OutcomeKind {
    pub const ALL: [OutcomeKind; 6] = [
        OutcomeKind::Majority,
        OutcomeKind::Early,
        OutcomeKind::Fallback,
        OutcomeKind::NoCommand,
        OutcomeKind::Aborted,
        OutcomeKind::Stopped,
    ];

    pub fn name(self) -> &'static str {
        match self {
            OutcomeKind::Majority => "majority",
            OutcomeKind::Early => "early",
            OutcomeKind::Fallback => "fallback",
            OutcomeKind::NoCommand => "no_command",
            OutcomeKind::Aborted => "aborted",
            OutcomeKind::Stopped => "stopped",
        }
    }
}

impl Outcome {
    pub fn kind(&self) -> OutcomeKind {
        match self {
            Outcome::Majority { .. } => OutcomeKind::Majority,
            Outcome::Early { .. } => OutcomeKind::Early,
            Outcome::Fallback { .. } => OutcomeKind::Fallback,
            Outcome::NoCommand { .. } => OutcomeKind::NoCommand,
            Outcome::Aborted { .. } => OutcomeKind::Aborted,
            Outcome::Stopped => OutcomeKind::Stopped,
        }
    }

    /// The pre-shape to command, if any.
    pub fn preshape(&self) -> Option<Preshape> {
        match self {
            Outcome::Majority { preshape }
            | Outcome::Early { preshape }
            | Outcome::Fallback { preshape, .. } => Some(*preshape),
            Outcome::NoCommand { .. } | Outcome::Aborted { .. } | Outcome::Stopped => None,
        }
    }
}

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Outcome::Majority { preshape } => write!(f, "{preshape} (majority vote)"),
            Outcome::Early { preshape } => write!(f, "{preshape} (early decision)"),
            Outcome::Fallback { preshape, why } => {
                write!(f, "{preshape} (fallback: {why})")
            }
            Outcome::NoCommand { why } => write!(f, "no command ({why})"),
            Outcome::Aborted { error } => write!(f, "aborted, no command: {error}"),
            Outcome::Stopped => write!(f, "stopped before a decision, no command"),
        }
    }
}

/// The outcome plus the evidence it was taken on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Decision {
    pub outcome: Outcome,
    /// Arg-max counts per class, indexed like [`Class`].
    pub votes: [u32; Class::COUNT],
    /// Frames that produced a valid output.
    pub frames: u32,
    /// Frames whose output was refused.
    pub invalid_frames: u32,
}

/// Accumulates one approach window.
#[derive(Debug, Clone)]
pub struct Vote {
    cfg: PolicyConfig,
    counts: [u32; Class::COUNT],
    /// Sum of the arg-max probability of the frames voting for each class.
    confidence_sum: [f64; Class::COUNT],
    frames: u32,
    invalid: u32,
}

/// Result of observing one frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    Continue,
    /// The frame's output was refused and skipped.
    Skipped(InvalidOutput),
    Decided(Decision),
}

impl Vote {
    pub fn new(cfg: PolicyConfig) -> Self {
        Vote {
            cfg,
            counts: [0; Class::COUNT],
            confidence_sum: [0.0; Class::COUNT],
            frames: 0,
            invalid: 0,
        }
    }

    /// Adds one raw model output.
    pub fn observe(&mut self, raw: [f32; Class::COUNT]) -> Step {
        let p = match Probabilities::new(raw) {
            Ok(p) => p,
            Err(e) => {
                self.invalid += 1;
                return match self.cfg.on_invalid {
                    OnInvalid::Skip => Step::Skipped(e),
                    OnInvalid::Abort => Step::Decided(self.decision(Outcome::Aborted {
                        error: format!("invalid model output: {e}"),
                    })),
                };
            }
        };
        let (class, prob) = p.argmax();
        self.counts[class.index()] += 1;
        self.confidence_sum[class.index()] += f64::from(prob);
        self.frames += 1;
        match self.early() {
            Some(preshape) => Step::Decided(self.decision(Outcome::Early { preshape })),
            None => Step::Continue,
        }
    }

    /// Decides at the end of the window.
    pub fn finish(&self) -> Decision {
        if self.frames == 0 {
            let error = match self.invalid {
                0 => "no frame was classified in the approach window".to_string(),
                n => format!("all {n} frames of the window had invalid model outputs"),
            };
            return self.decision(Outcome::Aborted { error });
        }
        let outcome = match self.judge() {
            Ok(preshape) => Outcome::Majority { preshape },
            Err(why) => match self.cfg.fallback {
                Some(preshape) => Outcome::Fallback { preshape, why },
                None => Outcome::NoCommand { why },
            },
        };
        self.decision(outcome)
    }

    /// Ends the approach without actuation (source or classifier failure).
    pub fn abort(&self, error: String) -> Decision {
        self.decision(Outcome::Aborted { error })
    }

    /// Ends the window without a decision: a stop was requested.
    pub fn stop(&self) -> Decision {
        self.decision(Outcome::Stopped)
    }

    fn decision(&self, outcome: Outcome) -> Decision {
        Decision {
            outcome,
            votes: self.counts,
            frames: self.frames,
            invalid_frames: self.invalid,
        }
    }

    /// Pre-shape classes sorted by votes, most first (stable on ties).
    fn ranking(&self) -> Vec<(Preshape, u32)> {
        let mut r: Vec<_> = Preshape::ALL
            .into_iter()
            .map(|p| (p, self.counts[Class::from(p).index()]))
            .collect();
        r.sort_by_key(|r| std::cmp::Reverse(r.1));
        r
    }

    fn grasp_votes(&self) -> u32 {
        self.ranking().iter().map(|r| r.1).sum()
    }

    fn mean_confidence(&self, p: Preshape) -> f64 {
        let i = Class::from(p).index();
        self.confidence_sum[i] / f64::from(self.counts[i].max(1))
    }

    /// The majority pre-shape, or why it cannot be trusted.
    fn judge(&self) -> Result<Preshape, LowConfidence> {
        let ranking = self.ranking();
        let (winner, top) = ranking[0];
        let total = self.grasp_votes();
        if total == 0 {
            return Err(LowConfidence::NoVotes);
        }
        let tied: Vec<_> = ranking.iter().filter(|r| r.1 == top).map(|r| r.0).collect();
        if tied.len() > 1 {
            return Err(LowConfidence::Tie { between: tied });
        }
        if total < self.cfg.min_votes {
            return Err(LowConfidence::TooFewVotes {
                votes: total,
                min: self.cfg.min_votes,
            });
        }
        let share = f64::from(top) / f64::from(total);
        if share < self.cfg.min_share {
            return Err(LowConfidence::Share {
                share,
                min: self.cfg.min_share,
            });
        }
        let mean = self.mean_confidence(winner);
        if mean < self.cfg.min_confidence {
            return Err(LowConfidence::Confidence {
                mean,
                min: self.cfg.min_confidence,
            });
        }
        Ok(winner)
    }

    fn early(&self) -> Option<Preshape> {
        let margin = self.cfg.early_margin?;
        let ranking = self.ranking();
        let lead = ranking[0].1 - ranking[1].1;
        if lead < margin {
            return None;
        }
        self.judge().ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_hot(c: Class, p: f32) -> [f32; Class::COUNT] {
        let rest = (1.0 - p) / 4.0;
        let mut v = [rest; Class::COUNT];
        v[c.index()] = p;
        v
    }

    fn run(cfg: PolicyConfig, frames: &[(Class, f32)]) -> Decision {
        let mut vote = Vote::new(cfg);
        for &(c, p) in frames {
            if let Step::Decided(d) = vote.observe(one_hot(c, p)) {
                return d;
            }
        }
        vote.finish()
    }

    #[test]
    fn majority_ignores_no_grasp() {
        let mut frames = vec![(Class::NoGrasp, 0.9); 10];
        frames.extend([(Class::Pinch, 0.8); 4]);
        frames.extend([(Class::Power, 0.8); 2]);
        let d = run(PolicyConfig::default(), &frames);
        assert_eq!(
            d.outcome,
            Outcome::Majority {
                preshape: Preshape::Pinch
            }
        );
        assert_eq!(d.votes, [2, 0, 4, 0, 10]);
        assert_eq!(d.frames, 16);
    }

    #[test]
    fn early_decision_once_the_margin_is_reached() {
        let cfg = PolicyConfig {
            early_margin: Some(3),
            ..PolicyConfig::default()
        };
        let frames = [
            (Class::Lateral, 0.9),
            (Class::Power, 0.9),
            (Class::Lateral, 0.9),
            (Class::Lateral, 0.9),
            (Class::Lateral, 0.9), // lead 4 - 1 = 3: decide here
            (Class::Power, 0.9),
        ];
        let d = run(cfg, &frames);
        assert_eq!(
            d.outcome,
            Outcome::Early {
                preshape: Preshape::Lateral
            }
        );
        assert_eq!(d.frames, 5);
    }

    #[test]
    fn weak_votes_fall_back_or_send_nothing() {
        let cfg = PolicyConfig {
            fallback: Some(Preshape::Lateral),
            ..PolicyConfig::default()
        };
        let fb = |frames: &[(Class, f32)]| match run(cfg.clone(), frames).outcome {
            Outcome::Fallback { preshape, why } => {
                assert_eq!(preshape, Preshape::Lateral);
                why
            }
            other => panic!("expected a fallback, got {other}"),
        };
        assert_eq!(fb(&[(Class::NoGrasp, 0.9); 5]), LowConfidence::NoVotes);
        assert!(matches!(
            fb(&[(Class::Pinch, 0.9), (Class::Pinch, 0.9)]),
            LowConfidence::TooFewVotes { votes: 2, min: 3 }
        ));
        assert!(matches!(
            fb(&[(Class::Pinch, 0.9), (Class::Power, 0.9)]),
            LowConfidence::Tie { .. }
        ));
        assert!(matches!(
            fb(&[(Class::Pinch, 0.3); 6]),
            LowConfidence::Confidence { .. }
        ));
        let spread = [
            (Class::Pinch, 0.9),
            (Class::Pinch, 0.9),
            (Class::Power, 0.9),
            (Class::Lateral, 0.9),
            (Class::Pinch3, 0.9),
        ];
        assert!(matches!(fb(&spread), LowConfidence::Share { .. }));
        let none = PolicyConfig {
            fallback: None,
            ..PolicyConfig::default()
        };
        let d = run(none, &[(Class::NoGrasp, 0.9); 5]);
        assert_eq!(d.outcome.preshape(), None);
    }

    #[test]
    fn nan_aborts_without_a_preshape() {
        let mut vote = Vote::new(PolicyConfig::default());
        for _ in 0..5 {
            assert_eq!(vote.observe(one_hot(Class::Power, 0.9)), Step::Continue);
        }
        let mut bad = one_hot(Class::Power, 0.9);
        bad[2] = f32::NAN;
        match vote.observe(bad) {
            Step::Decided(d) => {
                assert!(matches!(d.outcome, Outcome::Aborted { .. }));
                assert_eq!(d.outcome.preshape(), None);
                assert_eq!(d.invalid_frames, 1);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn skipped_invalid_frames_do_not_vote_and_cannot_make_a_fallback() {
        let cfg = PolicyConfig {
            on_invalid: OnInvalid::Skip,
            ..PolicyConfig::default()
        };
        let mut vote = Vote::new(cfg);
        let inf = [f32::INFINITY, 0.0, 0.0, 0.0, 0.0];
        for _ in 0..4 {
            assert!(matches!(vote.observe(inf), Step::Skipped(_)));
        }
        // Only invalid frames: abort, never the fallback pre-shape.
        let d = vote.finish();
        assert!(matches!(d.outcome, Outcome::Aborted { .. }));
        for _ in 0..3 {
            vote.observe(one_hot(Class::Pinch3, 0.7));
        }
        let d = vote.finish();
        assert_eq!(d.outcome.preshape(), Some(Preshape::Pinch3));
        assert_eq!(d.invalid_frames, 4);
    }

    #[test]
    fn an_empty_window_is_an_error_not_a_fallback() {
        let d = Vote::new(PolicyConfig::default()).finish();
        assert!(matches!(d.outcome, Outcome::Aborted { .. }));
    }

    #[test]
    fn config_validation_names_the_field() {
        let bad = PolicyConfig {
            window_s: f64::NAN,
            ..PolicyConfig::default()
        };
        assert!(bad.validate().unwrap_err().to_string().contains("window_s"));
        // Issue 60, case 7: finite but no time span (Duration panicked).
        for window_s in [1e30, MAX_WINDOW_S * 1.01] {
            let bad = PolicyConfig {
                window_s,
                ..PolicyConfig::default()
            };
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains("window_s") && e.contains("at most"), "{e}");
        }
        let huge = PolicyConfig {
            window_s: 1e308,
            ..PolicyConfig::default()
        };
        let e = huge.validate().unwrap_err().to_string();
        assert!(e.contains("got 1e308") && e.len() < 120, "{e}");
        let longest = PolicyConfig {
            window_s: MAX_WINDOW_S,
            ..PolicyConfig::default()
        };
        assert!(longest.validate().is_ok());
        let _ = std::time::Duration::from_secs_f64(longest.window_s);
        let bad = PolicyConfig {
            early_margin: Some(0),
            ..PolicyConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("early_margin"));
    }
}
