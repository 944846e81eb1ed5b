//! One approach, as in the paper's demo: after the trigger, classify the
//! frames of the window, decide, send the pre-shape, then close the fingers
//! after the closure trigger. Nothing is sent unless the decision names a
//! pre-shape, and a command counts as done only once acknowledged.

use crate::classifier::{FrameClassifier, Probabilities};
use crate::feed::{FeedItem, FeedMode, FeedStats, FrameFeed};
use crate::link::Hand;
use crate::policy::{Decision, PolicyConfig, Step, Vote};
use crate::protocol::{preshape_command, Command, HandState};
use crate::source::FrameSource;
use crate::trigger::Trigger;
use anyhow::Result;
use grasp_schema::taxonomy::{Class, Preshape};
use serde::Serialize;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// How long past the window a live feed may stall before the window is
/// closed with the frames seen so far.
const LIVE_GRACE: Duration = Duration::from_millis(500);

/// One classified frame.
#[derive(Debug, Clone, Serialize)]
pub struct FramePrediction {
    pub index: u64,
    pub time_s: f64,
    pub probabilities: [f32; Class::COUNT],
    /// Arg-max class; `None` when the output was invalid.
    pub class: Option<Class>,
    pub inference_ms: f64,
}

/// The classification part of an approach.
#[derive(Debug, Clone, Serialize)]
pub struct WindowReport {
    pub decision: Decision,
    pub predictions: Vec<FramePrediction>,
    pub feed: FeedStats,
    /// From the trigger to the decision.
    pub decision_ms: f64,
}

/// An acknowledged command.
#[derive(Debug, Clone, Serialize)]
pub struct CommandReport {
    pub command: &'static str,
    pub preshape: Option<Preshape>,
    pub seq: u8,
    pub attempts: u32,
    pub hand_state: HandState,
    /// From the first transmission to the ACK.
    pub link_ms: f64,
    /// From the trigger to the ACK.
    pub since_trigger_ms: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct ApproachReport {
    pub window: WindowReport,
    pub preshape: Option<CommandReport>,
    pub closure: Option<CommandReport>,
    /// Link failure, if the hand could not be commanded.
    pub link_error: Option<String>,
}

/// Classifies the approach window. `t0` is the trigger time. Returns the
/// source for the next approach.
pub fn classify_window(
    source: Box<dyn FrameSource>,
    mode: FeedMode,
    classifier: &mut dyn FrameClassifier,
    policy: &PolicyConfig,
    t0: Instant,
    on_frame: &mut dyn FnMut(&FramePrediction),
) -> Result<(Box<dyn FrameSource>, WindowReport)> {
    let feed = FrameFeed::start(source, mode)?;
    let window = Duration::from_secs_f64(policy.window_s);
    let deadline = match mode {
        FeedMode::Latest => Some(t0 + window + LIVE_GRACE),
        FeedMode::Lockstep => None,
    };
    let mut vote = Vote::new(policy.clone());
    let mut predictions = Vec::new();
    let decision = loop {
        let frame = match feed.next(deadline) {
            FeedItem::Frame(f) => f,
            FeedItem::Ended | FeedItem::TimedOut => break vote.finish(),
            FeedItem::Failed(e) => break vote.abort(format!("frame source failed: {e}")),
        };
        if frame.time_s >= policy.window_s {
            break vote.finish();
        }
        let started = Instant::now();
        let raw = match classifier.classify(&frame.image) {
            Ok(raw) => raw,
            Err(e) => {
                tracing::error!(frame = frame.index, "classifier failed: {e:#}");
                break vote.abort(format!("classifier failed on frame {}: {e:#}", frame.index));
            }
        };
        let prediction = FramePrediction {
            index: frame.index,
            time_s: frame.time_s,
            probabilities: raw,
            class: Probabilities::new(raw).ok().map(|p| p.argmax().0),
            inference_ms: started.elapsed().as_secs_f64() * 1e3,
        };
        on_frame(&prediction);
        predictions.push(prediction);
        match vote.observe(raw) {
            Step::Continue => {}
            Step::Skipped(e) => tracing::warn!(
                frame = frame.index,
                "invalid model output ({e}): frame left out of the vote"
            ),
            Step::Decided(d) => {
                if d.invalid_frames > 0 {
                    tracing::error!(
                        frame = frame.index,
                        ?raw,
                        "invalid model output: approach aborted, nothing sent to the hand"
                    );
                }
                break d;
            }
        }
    };
    let decision_ms = t0.elapsed().as_secs_f64() * 1e3;
    let (source, feed) = feed.finish();
    if feed.dropped > 0 {
        tracing::info!(
            dropped = feed.dropped,
            delivered = feed.delivered,
            "dropped stale frames to keep up with the camera"
        );
    }
    let report = WindowReport {
        decision,
        predictions,
        feed,
        decision_ms,
    };
    Ok((source, report))
}

/// Sends the decided pre-shape, then the closure once `closure` fires.
pub fn actuate(
    hand: &Hand,
    window: WindowReport,
    closure: Option<&mut dyn Trigger>,
    stop: &AtomicBool,
    t0: Instant,
) -> Result<ApproachReport> {
    let mut report = ApproachReport {
        window,
        preshape: None,
        closure: None,
        link_error: None,
    };
    let Some(preshape) = report.window.decision.outcome.preshape() else {
        tracing::warn!("no pre-shape sent: {}", report.window.decision.outcome);
        return Ok(report);
    };
    match send(hand, preshape_command(preshape), Some(preshape), t0) {
        Ok(c) => report.preshape = Some(c),
        Err(e) => {
            report.link_error = Some(e);
            return Ok(report);
        }
    }
    if let Some(closure) = closure {
        if closure.wait(stop)? {
            match send(hand, Command::Close, None, t0) {
                Ok(c) => report.closure = Some(c),
                Err(e) => report.link_error = Some(e),
            }
        }
    }
    Ok(report)
}

fn send(
    hand: &Hand,
    command: Command,
    preshape: Option<Preshape>,
    t0: Instant,
) -> Result<CommandReport, String> {
    let d = hand.send(command).map_err(|e| e.to_string())?;
    Ok(CommandReport {
        command: command.name(),
        preshape,
        seq: d.ack.seq,
        attempts: d.attempts,
        hand_state: d.ack.state,
        link_ms: d.elapsed.as_secs_f64() * 1e3,
        since_trigger_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}
