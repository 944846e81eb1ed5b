//! The policy on a recorded approach: what the hand would be commanded if
//! the frames of a video, with their own time stamps, reached `hannes-run`
//! one by one after a trigger at the first frame. `grasp-train eval` scores
//! it beside the paper's per-video vote; `hannes-run replay` takes the same
//! decision through [`Vote`] in its live loop.

use crate::vote::{Decision, PolicyConfig, Step, Vote};
use grasp_schema::taxonomy::Class;
use serde::Serialize;

/// The decision on a recorded approach and when it was taken.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordedDecision {
    pub decision: Decision,
    /// Frame time of the last frame the vote read, in seconds after the
    /// trigger (the first frame); `None` when no frame was read.
    pub at_s: Option<f64>,
}

/// Runs the policy over `frames` (frame time in seconds, raw model output),
/// in order, the trigger at the first frame: frames up to the window's end
/// vote, an early decision ends the window, and the window closes at the
/// first frame outside it or at the end of the recording.
pub fn decide_recorded<I>(cfg: &PolicyConfig, frames: I) -> RecordedDecision
where
    I: IntoIterator<Item = (f64, [f32; Class::COUNT])>,
{
    let mut vote = Vote::new(cfg.clone());
    let mut t0 = None;
    let mut at_s = None;
    for (t, raw) in frames {
        let since = t - *t0.get_or_insert(t);
        if !cfg.in_window(since) {
            break;
        }
        at_s = Some(since);
        if let Step::Decided(decision) = vote.observe(raw) {
            return RecordedDecision { decision, at_s };
        }
    }
    RecordedDecision {
        decision: vote.finish(),
        at_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vote::{LowConfidence, Outcome};
    use grasp_schema::taxonomy::Preshape;

    fn hot(c: Class) -> [f32; Class::COUNT] {
        let mut v = [0.025; Class::COUNT];
        v[c.index()] = 0.9;
        v
    }

    fn frames(classes: &[Class], fps: f64, start_s: f64) -> Vec<(f64, [f32; 5])> {
        let at = |i: usize| start_s + i as f64 / fps;
        classes
            .iter()
            .enumerate()
            .map(|(i, c)| (at(i), hot(*c)))
            .collect()
    }

    #[test]
    fn only_the_window_after_the_first_frame_votes() {
        // 2.5 frames/s, window 2 s: frames at 0, 0.4, ..., 1.6 vote (5);
        // the pinch frames from 2.0 s on never count, whatever the start.
        let mut seq = vec![Class::Lateral; 5];
        seq.extend([Class::Pinch; 6]);
        for start in [0.0, 3.2] {
            let d = decide_recorded(&PolicyConfig::default(), frames(&seq, 2.5, start));
            let lateral = Preshape::Lateral;
            assert_eq!(d.decision.outcome, Outcome::Majority { preshape: lateral });
            assert_eq!(d.decision.frames, 5);
            assert!((d.at_s.unwrap() - 1.6).abs() < 1e-9);
        }
    }

    #[test]
    fn an_early_decision_ends_the_window_at_its_frame() {
        let cfg = PolicyConfig {
            early_margin: Some(3),
            ..PolicyConfig::default()
        };
        let d = decide_recorded(&cfg, frames(&[Class::Pinch3; 8], 5.0, 1.0));
        let pinch3 = Preshape::Pinch3;
        assert_eq!(d.decision.outcome, Outcome::Early { preshape: pinch3 });
        assert!((d.at_s.unwrap() - 0.4).abs() < 1e-9);
    }

    #[test]
    fn a_weak_vote_falls_back_and_an_empty_recording_aborts() {
        let d = decide_recorded(
            &PolicyConfig::default(),
            frames(&[Class::NoGrasp; 5], 2.5, 0.0),
        );
        let why = LowConfidence::NoVotes;
        let power = Preshape::Power;
        assert_eq!(
            d.decision.outcome,
            Outcome::Fallback {
                preshape: power,
                why
            }
        );
        let d = decide_recorded(&PolicyConfig::default(), Vec::new());
        assert!(matches!(d.decision.outcome, Outcome::Aborted { .. }));
        assert_eq!(d.at_s, None);
    }
}
