//! One approach, as in the paper's demo: after the trigger, classify the
//! frames of the window, decide, send the pre-shape, then close the fingers
//! after the closure trigger. Nothing is sent unless the decision names a
//! pre-shape, and a command counts as done only once acknowledged.
//!
//! A decision has an age limit (`policy.max_decision_age_ms`): a pre-shape
//! not acknowledged within it after the decision is never sent again (the
//! link waits no longer, the hand refuses a late copy), no closure follows,
//! and the hand is opened if a copy may have reached it. The closure has
//! the same limit, counted from its trigger.
//!
//! The age of a decision is the time since the vote was settled
//! ([`WindowReport::decided_at`]), not since the capture of the frames it
//! was taken on: the limit bounds the delay the host and the link add
//! before the hand moves, which eats into the reach. How old the newest
//! frame is at the decision depends on the source (up to one frame
//! interval: 33 ms for a 30 frames/s camera, 400 ms for a recording at 2.5
//! frames/s) and is reported with each prediction's `time_s`; it does not
//! count against the limit. Nothing between the decision and the first
//! transmission waits for the source: [`classify_window`] hands back a
//! [`StoppedFeed`] whose capture thread may still be fetching the frame
//! after the window, to be joined after [`actuate`].
//!
//! Whenever a PRESHAPE or CLOSE may have reached the hand and the approach
//! does not end as decided (a closure that failed, expired or was never
//! triggered, a pre-shape whose ACK never came), OPEN is sent: the hand is
//! never left shaped or closed by an approach that failed. A CLOSE is sent
//! only while the hand says it is in the pre-shape it executed (after a
//! reconnect, what its HELLO says; see [`crate::link`]). The report says
//! what the hand last acknowledged ([`ApproachReport::hand`]).
//!
//! A stop (SIGINT, SIGTERM, SIGHUP: the `stop` flag) ends the approach
//! wherever it is: nothing new is sent after it (no pre-shape, no
//! retransmission, no closure), and if a PRESHAPE or CLOSE may have reached
//! the hand, OPEN is sent so the hand is not left shaped by a program that
//! is going away. The report records where it stopped ([`StopReport`]).

use crate::classifier::{FrameClassifier, Probabilities};
use crate::feed::{FeedItem, FeedMode, FeedStats, FrameFeed, StoppedFeed};
use crate::link::{Hand, LinkError};
use crate::policy::{Decision, Outcome, PolicyConfig, Step, Vote};
use crate::protocol::{command_name, preshape_command, Ack, Command, HandState, Status};
use crate::signals::Signal;
use crate::source::{FrameSource, SourceError};
use crate::trigger::{Trigger, TriggerError};
use grasp_schema::taxonomy::{Class, Preshape};
use serde::Serialize;
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long past the window a live feed may stall before the window is
/// closed with the frames seen so far.
const LIVE_GRACE: Duration = Duration::from_millis(500);

/// How often the window looks at the stop flag while it waits for a frame.
const STOP_POLL: Duration = Duration::from_millis(20);

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
    /// The frames of the window, as of the decision.
    pub feed: FeedStats,
    /// From the trigger to the decision.
    pub decision_ms: f64,
    /// When the vote was settled: the start of the decision's age.
    #[serde(skip)]
    pub decided_at: Instant,
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
    /// From what the command acts on (the decision for PRESHAPE, the
    /// closure trigger for CLOSE) to the ACK.
    pub age_ms: f64,
}

/// A command dropped because it became older than the age limit.
#[derive(Debug, Clone, Serialize)]
pub struct ExpiredCommand {
    pub command: &'static str,
    pub preshape: Option<Preshape>,
    /// Its age when the host gave up (from the decision, or from the
    /// closure trigger).
    pub age_ms: f64,
    pub limit_ms: f64,
    /// Copies transmitted before it expired (0: never sent; at least 1
    /// when the hand refused it).
    pub transmissions: u32,
    /// A copy reached the hand after the deadline and was refused.
    pub refused_by_hand: bool,
}

/// Where in the approach a stop was noticed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopPhase {
    /// Before any pre-shape was sent.
    Window,
    /// While the PRESHAPE was being sent, or just after its ACK.
    Preshape,
    /// Between the pre-shape and the closure trigger.
    ClosureDelay,
    /// While the CLOSE was being sent, or just after its ACK.
    Closure,
}

impl fmt::Display for StopPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StopPhase::Window => "during the approach window",
            StopPhase::Preshape => "while the pre-shape was being sent",
            StopPhase::ClosureDelay => "while waiting for the closure",
            StopPhase::Closure => "while the closure was being sent",
        })
    }
}

/// An approach ended by a stop request.
#[derive(Debug, Clone, Serialize)]
pub struct StopReport {
    /// The signal, when a signal set the stop flag.
    pub signal: Option<Signal>,
    pub phase: StopPhase,
    /// A PRESHAPE or CLOSE may have reached the hand: OPEN was sent (see
    /// the report's `reopened` and `link_error`).
    pub may_have_moved: bool,
}

impl StopReport {
    fn new(phase: StopPhase, may_have_moved: bool) -> Self {
        StopReport {
            signal: crate::signals::received(),
            phase,
            may_have_moved,
        }
    }
}

/// What the hand said in the last ACK the host received: its state and
/// configuration then.
#[derive(Debug, Clone, Serialize)]
pub struct HandAck {
    /// The command acknowledged (HELLO after a reconnect).
    pub command: String,
    /// `ok`, or why the hand did not execute it (`expired`, ...).
    pub status: String,
    pub state: HandState,
    /// The pre-shape whose configuration the hand was in.
    pub preshape: Option<Preshape>,
    pub configuration: grasp_schema::taxonomy::HandConfiguration,
}

impl HandAck {
    pub fn of(ack: &Ack) -> Self {
        HandAck {
            command: command_name(ack.cmd),
            status: format!("{:?}", ack.status).to_lowercase(),
            state: ack.state,
            preshape: Preshape::of_configuration(ack.config),
            configuration: ack.config,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct ApproachReport {
    pub window: WindowReport,
    pub preshape: Option<CommandReport>,
    pub closure: Option<CommandReport>,
    /// The pre-shape or closure that was too old to execute.
    pub expired: Option<ExpiredCommand>,
    /// OPEN sent after an expired pre-shape a copy of which may have been
    /// executed in time (its ACK lost), or after a stop.
    pub reopened: Option<CommandReport>,
    /// Link failure, if the hand could not be commanded.
    pub link_error: Option<String>,
    /// The approach was stopped (a signal) before it ended.
    pub stopped: Option<StopReport>,
    /// The closure trigger could never fire (stdin ended): no closure,
    /// the hand opened.
    pub closure_missed: Option<String>,
    /// What the hand last acknowledged when the approach ended.
    pub hand: Option<HandAck>,
}

/// Classifies the approach window. `t0` is the trigger time. Returns as
/// soon as the vote is settled, with the stopped feed: join it (after
/// actuating) for the source of the next approach.
pub fn classify_window(
    source: Box<dyn FrameSource>,
    mode: FeedMode,
    classifier: &mut dyn FrameClassifier,
    policy: &PolicyConfig,
    t0: Instant,
    on_frame: &mut dyn FnMut(&FramePrediction),
) -> Result<(StoppedFeed, WindowReport), SourceError> {
    let never = AtomicBool::new(false);
    classify_window_until(source, mode, classifier, policy, t0, &never, on_frame)
}

/// [`classify_window`] that ends as soon as `stop` is set, with the
/// outcome [`crate::policy::Outcome::Stopped`] (no decision).
pub fn classify_window_until(
    source: Box<dyn FrameSource>,
    mode: FeedMode,
    classifier: &mut dyn FrameClassifier,
    policy: &PolicyConfig,
    t0: Instant,
    stop: &AtomicBool,
    on_frame: &mut dyn FnMut(&FramePrediction),
) -> Result<(StoppedFeed, WindowReport), SourceError> {
    let feed = FrameFeed::start(source, mode)?;
    let window = Duration::from_secs_f64(policy.window_s);
    let deadline = match mode {
        FeedMode::Latest => Some(t0 + window + LIVE_GRACE),
        FeedMode::Lockstep => None,
    };
    let mut vote = Vote::new(policy.clone());
    let mut predictions = Vec::new();
    classifier.begin_approach();
    let decision = loop {
        let frame = match next_unless_stopped(&feed, deadline, stop) {
            None => break vote.stop(),
            Some(FeedItem::Frame(f)) => f,
            Some(FeedItem::Ended | FeedItem::TimedOut) => break vote.finish(),
            Some(FeedItem::Failed(e)) => break vote.abort(format!("frame source failed: {e}")),
        };
        if !policy.in_window(frame.time_s) {
            break vote.finish();
        }
        let started = Instant::now();
        let raw = match classifier.classify(&frame.image, frame.time_s) {
            Ok(raw) => raw,
            Err(e) => {
                let e = grasp_support::error_chain(&e);
                tracing::error!(frame = frame.index, "classifier failed: {e}");
                break vote.abort(format!("classifier failed on frame {}: {e}", frame.index));
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
    let decided_at = Instant::now();
    let decision_ms = decided_at.duration_since(t0).as_secs_f64() * 1e3;
    // Not joined: the capture thread may be inside the source for another
    // frame interval, and the decision's age is running.
    let (stopped, feed) = feed.stop();
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
        decided_at,
    };
    Ok((stopped, report))
}

/// The feed's next item, waiting until `deadline` (forever if `None`);
/// `None` once `stop` is set, looked at every [`STOP_POLL`] while waiting.
fn next_unless_stopped(
    feed: &FrameFeed,
    deadline: Option<Instant>,
    stop: &AtomicBool,
) -> Option<FeedItem> {
    loop {
        if stop.load(Ordering::SeqCst) {
            return None;
        }
        let slice = Instant::now() + STOP_POLL;
        let until = deadline.map_or(slice, |d| d.min(slice));
        match feed.next(Some(until)) {
            FeedItem::TimedOut if deadline.is_none_or(|d| Instant::now() < d) => {}
            item => return Some(item),
        }
    }
}

/// Sends the decided pre-shape, then the closure once `closure` fires;
/// neither is executed once older than `max_age`, and nothing is sent once
/// `stop` is set (see the module docs).
pub fn actuate(
    hand: &Hand,
    window: WindowReport,
    closure: Option<&mut dyn Trigger>,
    stop: &AtomicBool,
    t0: Instant,
    max_age: Duration,
) -> Result<ApproachReport, TriggerError> {
    let mut report = ApproachReport {
        window,
        preshape: None,
        closure: None,
        expired: None,
        reopened: None,
        link_error: None,
        stopped: None,
        closure_missed: None,
        hand: None,
    };
    let act = Actuation {
        hand,
        stop,
        t0,
        max_age,
    };
    act.commands(&mut report, closure)?;
    report.hand = hand.last_ack().as_ref().map(HandAck::of);
    Ok(report)
}

impl Actuation<'_> {
    /// The pre-shape, then the closure (see [`actuate`]).
    fn commands(
        &self,
        report: &mut ApproachReport,
        closure: Option<&mut dyn Trigger>,
    ) -> Result<(), TriggerError> {
        let (act, hand, stop, t0) = (self, self.hand, self.stop, self.t0);
        let Some(preshape) = report.window.decision.outcome.preshape() else {
            if report.window.decision.outcome == Outcome::Stopped {
                report.stopped = Some(StopReport::new(StopPhase::Window, false));
            }
            tracing::warn!("no pre-shape sent: {}", report.window.decision.outcome);
            return Ok(());
        };
        if act.stop_requested() {
            // Decided, but the stop came before the first transmission.
            act.stop_and_open(report, StopPhase::Window, false);
            return Ok(());
        }
        let order = Order {
            command: preshape_command(preshape),
            preshape: Some(preshape),
            since: report.window.decided_at,
            max_age: Some(self.max_age),
        };
        if !act.record_preshape(report, order.send(hand, t0, Some(stop))) {
            return Ok(());
        }
        let Some(closure) = closure else {
            return Ok(());
        };
        let fired = match closure.wait(stop) {
            Ok(fired) => fired,
            Err(e) => {
                // The hand is pre-shaped and nothing will close it.
                act.reopen(report, "after the closure trigger failed");
                return Err(e);
            }
        };
        if act.stop_requested() {
            act.stop_and_open(report, StopPhase::ClosureDelay, true);
            return Ok(());
        }
        if !fired {
            // The trigger can never fire (e.g. stdin closed): no closure
            // will come, so the hand is not left pre-shaped.
            let why = format!(
                "the closure trigger ({}) ended before it fired: no closure",
                closure.describe()
            );
            tracing::error!("{why}; opening the hand");
            report.closure_missed = Some(why);
            act.reopen(report, "after the closure trigger ended");
            return Ok(());
        }
        let order = Order {
            command: Command::Close,
            preshape: None,
            since: Instant::now(),
            max_age: Some(self.max_age),
        };
        act.record_closure(report, order.send(hand, t0, Some(stop)));
        Ok(())
    }
}

/// What sending the commands of one approach needs.
struct Actuation<'a> {
    hand: &'a Hand,
    stop: &'a AtomicBool,
    t0: Instant,
    max_age: Duration,
}

impl Actuation<'_> {
    fn stop_requested(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// Records how the PRESHAPE went; whether the approach goes on to the
    /// closure.
    fn record_preshape(&self, report: &mut ApproachReport, sent: Sent) -> bool {
        match sent {
            Sent::Acked(c) => {
                report.preshape = Some(c);
                if self.stop_requested() {
                    // The stop came with the ACK: no closure follows.
                    self.stop_and_open(report, StopPhase::Preshape, true);
                    return false;
                }
                true
            }
            Sent::Expired(e) => {
                tracing::error!(
                    "stale decision: {} was decided {:.0} ms ago, over the {:.0} ms limit; \
                     not sent, no closure",
                    e.preshape.map_or("the pre-shape".into(), |p| p.to_string()),
                    e.age_ms,
                    e.limit_ms
                );
                let may_have_reached = e.transmissions > 0 && !e.refused_by_hand;
                report.expired = Some(e);
                if may_have_reached {
                    self.reopen(report, "after the stale decision");
                }
                false
            }
            Sent::Stopped { transmissions } => {
                self.stop_and_open(report, StopPhase::Preshape, transmissions > 0);
                false
            }
            Sent::Failed {
                error,
                transmissions,
            } => {
                report.link_error = Some(error);
                if transmissions > 0 {
                    // A copy may have been executed, its ACK lost.
                    self.reopen(report, "after the unacknowledged pre-shape");
                }
                false
            }
        }
    }

    /// Records how the CLOSE went.
    fn record_closure(&self, report: &mut ApproachReport, sent: Sent) {
        match sent {
            Sent::Acked(c) => {
                report.closure = Some(c);
                if self.stop_requested() {
                    self.stop_and_open(report, StopPhase::Closure, true);
                }
            }
            // The pre-shape reached the hand, and the CLOSE may have: the
            // hand is opened whenever the closure is not confirmed.
            Sent::Expired(e) => {
                tracing::error!(
                    "closure not acknowledged within {:.0} ms of its trigger \
                     ({} copies sent): not sent again; opening the hand",
                    e.limit_ms,
                    e.transmissions
                );
                report.expired = Some(e);
                self.reopen(report, "after the expired closure");
            }
            Sent::Stopped { .. } => self.stop_and_open(report, StopPhase::Closure, true),
            Sent::Failed { error, .. } => {
                tracing::error!("closure failed: {error}; opening the hand");
                report.link_error = Some(error);
                self.reopen(report, "after the failed closure");
            }
        }
    }

    /// Ends the approach on a stop; opens the hand if a PRESHAPE or CLOSE
    /// may have reached it (when in doubt, open).
    fn stop_and_open(&self, report: &mut ApproachReport, phase: StopPhase, moved: bool) {
        let stop = StopReport::new(phase, moved);
        tracing::warn!(
            "stopped by {} {phase}: nothing more is sent{}",
            stop.signal.map_or("request".into(), |s| s.name()),
            if moved { "; opening the hand" } else { "" }
        );
        report.stopped = Some(stop);
        if moved {
            self.reopen(report, "after the stop");
        }
    }

    /// Opens the hand (after an expired pre-shape that may have been
    /// executed, or a stop). Never stopped itself: opening is always safe.
    fn reopen(&self, report: &mut ApproachReport, why: &str) {
        let order = Order {
            command: Command::Open,
            preshape: None,
            since: Instant::now(),
            max_age: None, // opening is always safe
        };
        match order.send(self.hand, self.t0, None) {
            Sent::Acked(c) => report.reopened = Some(c),
            Sent::Expired(_) | Sent::Stopped { .. } => {
                unreachable!("OPEN has no age limit and no stop")
            }
            Sent::Failed { error, .. } => {
                tracing::error!("cannot open the hand {why}: {error}");
                // Kept after the error that made the approach open the hand.
                report.link_error = Some(match report.link_error.take() {
                    Some(first) => format!("{first}; then cannot open the hand: {error}"),
                    None => error,
                });
            }
        }
    }
}

/// A command with what its age counts from.
struct Order {
    command: Command,
    preshape: Option<Preshape>,
    since: Instant,
    max_age: Option<Duration>,
}

enum Sent {
    Acked(CommandReport),
    Expired(ExpiredCommand),
    /// A stop came first; copies transmitted before it.
    Stopped {
        transmissions: u32,
    },
    /// Not acknowledged; `transmissions`: copies sent (a copy may have
    /// been executed).
    Failed {
        error: String,
        transmissions: u32,
    },
}

impl Order {
    fn send(&self, hand: &Hand, t0: Instant, stop: Option<&AtomicBool>) -> Sent {
        let expires = self.max_age.map(|a| self.since + a);
        let expired = |transmissions, refused_by_hand| {
            Sent::Expired(ExpiredCommand {
                command: self.command.name(),
                preshape: self.preshape,
                age_ms: ms(self.since.elapsed()),
                limit_ms: self.max_age.map_or(f64::INFINITY, ms),
                transmissions,
                refused_by_hand,
            })
        };
        let before = hand.stats().transmissions;
        match hand.send_unless_stopped(self.command, expires, stop) {
            Ok(d) => Sent::Acked(CommandReport {
                command: self.command.name(),
                preshape: self.preshape,
                seq: d.ack.seq,
                attempts: d.attempts,
                hand_state: d.ack.state,
                link_ms: ms(d.elapsed),
                since_trigger_ms: ms(t0.elapsed()),
                age_ms: ms(self.since.elapsed()),
            }),
            Err(LinkError::Expired { transmissions, .. }) => expired(transmissions, false),
            Err(LinkError::Rejected {
                status: Status::Expired,
                ..
            }) => expired(1, true),
            Err(LinkError::Stopped { transmissions, .. }) => Sent::Stopped { transmissions },
            Err(e) => Sent::Failed {
                error: e.to_string(),
                // At least those the link counted (a heartbeat in between
                // only makes it open the hand when in doubt).
                transmissions: (hand.stats().transmissions - before) as u32,
            },
        }
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}
