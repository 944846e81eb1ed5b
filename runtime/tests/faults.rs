//! Whole approaches against the simulated hand with injected, seeded link
//! faults (drop, corrupt, duplicate, short and long delays, disconnects, a
//! mix; `simhand::FaultSpec`), and a decision taken while the link is down.
//!
//! Every case asserts, from the hand's own event log:
//! - never a wrong pre-shape: each executed pre-shape is the one decided by
//!   the approach it belongs to (consecutive approaches decide different
//!   ones, so a late copy of the previous decision would show);
//! - never a stale one: each was executed within the age limit of its
//!   decision, and each closure within the limit of its trigger and after
//!   its approach's pre-shape;
//! - the hand opens on link loss: unplugged while shaped, it opens itself;
//! - the link recovers when the fault ends: a clean approach afterwards is
//!   executed.
//!
//! Nothing here asserts how long anything took: ages are differences of
//! recorded instants compared with the age limit, the rest is event order
//! and counts, so a loaded machine only makes approaches expire (which the
//! checks accept), never makes a check fail.

mod common;

use common::{eventually, frames_of, start_hand, FakeModel};
use grasp_schema::taxonomy::{Class, Preshape};
use runtime::approach::{actuate, classify_window, ApproachReport};
use runtime::feed::FeedMode;
use runtime::link::{Hand, LinkConfig};
use runtime::policy::{Outcome, PolicyConfig};
use runtime::protocol::HandState;
use runtime::session::{SessionSummary, EXIT_EXPIRED};
use runtime::simhand::{FaultKind, FaultSpec, HandEvent, PtyHand};
use runtime::source::{MemorySource, Pacing};
use runtime::trigger::{Trigger, TriggerError};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// The age limit under test (the default).
const LIMIT: Duration = Duration::from_millis(300);
/// Slack for the hand clock's whole milliseconds in the age checks; a late
/// execution the faults could cause is hundreds of milliseconds late.
const SLACK: Duration = Duration::from_millis(5);
/// Approaches under faults per case.
const APPROACHES: usize = 8;

/// Heartbeats often, a short watchdog (so a disconnect opens the hand), and
/// attempts spanning more than the age limit (10 x 40 ms), so the limit,
/// not the retry count, ends an unacknowledged pre-shape.
fn link() -> LinkConfig {
    LinkConfig {
        ack_timeout_ms: 40,
        retries: 9,
        heartbeat_interval_ms: 30,
        watchdog_ms: 300,
        reconnect_interval_ms: 20,
        reconnect_timeout_ms: 5000,
    }
}

/// A timer closure that records when it fired.
struct RecordingTimer {
    delay: Duration,
    fired: Option<Instant>,
}

impl Trigger for RecordingTimer {
    fn wait(&mut self, stop: &AtomicBool) -> Result<bool, TriggerError> {
        let fired = runtime::trigger::Timer(self.delay).wait(stop)?;
        self.fired = Some(Instant::now());
        Ok(fired)
    }

    fn describe(&self) -> String {
        "recording timer".into()
    }
}

/// One approach as the test saw it.
struct Approach {
    preshape: Preshape,
    decided: Instant,
    closure_fired: Option<Instant>,
    limit: Duration,
    report: ApproachReport,
}

fn approach(hand: &Hand, preshape: Preshape, limit: Duration) -> Approach {
    let class = Class::from(preshape);
    let source =
        MemorySource::new(frames_of(&[class; 12]), 30.0, Pacing::AsFastAsPossible).unwrap();
    let t0 = Instant::now();
    let (_, window) = classify_window(
        Box::new(source),
        FeedMode::Lockstep,
        &mut FakeModel::new(),
        &PolicyConfig::default(),
        t0,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(window.decision.outcome, Outcome::Majority { preshape });
    let decided = window.decided_at;
    let mut closure = RecordingTimer {
        delay: Duration::from_millis(20),
        fired: None,
    };
    let stop = AtomicBool::new(false);
    let report = actuate(hand, window, Some(&mut closure), &stop, t0, limit).unwrap();
    Approach {
        preshape,
        decided,
        closure_fired: closure.fired,
        limit,
        report,
    }
}

/// Checks the hand's log against the approaches (see the module docs).
fn check_safety(approaches: &[Approach], events: &[(Instant, HandEvent)]) {
    let owner = |t: Instant| approaches.iter().rposition(|a| a.decided <= t);
    let mut executed = vec![false; approaches.len()];
    for (t, e) in events {
        match e {
            HandEvent::Preshape { preshape, .. } => {
                let k = owner(*t).unwrap_or_else(|| panic!("pre-shape before any decision"));
                let a = &approaches[k];
                assert_eq!(
                    *preshape,
                    Some(a.preshape),
                    "wrong pre-shape in approach {k}"
                );
                let age = *t - a.decided;
                assert!(
                    age <= a.limit + SLACK,
                    "approach {k}: {:?} executed {age:?} after its decision (limit {:?})",
                    a.preshape,
                    a.limit
                );
                executed[k] = true;
            }
            HandEvent::Close { .. } => {
                let k = owner(*t).expect("closure before any decision");
                let a = &approaches[k];
                assert!(executed[k], "approach {k}: closure without its pre-shape");
                let fired = a.closure_fired.expect("closure trigger fired");
                assert!(*t >= fired, "approach {k}: closure before its trigger");
                let age = *t - fired;
                assert!(
                    age <= a.limit + SLACK,
                    "approach {k}: closure executed {age:?} after its trigger"
                );
            }
            _ => {}
        }
    }
    for (k, a) in approaches.iter().enumerate() {
        let r = &a.report;
        if r.preshape.is_some() {
            assert!(executed[k], "approach {k}: acknowledged but not executed");
        }
        if r.expired.is_some() || r.preshape.is_none() {
            assert!(
                r.closure.is_none(),
                "approach {k}: closure after no pre-shape"
            );
        }
        if let Some(open) = &r.reopened {
            assert_eq!(open.hand_state, HandState::Open);
        }
    }
}

/// Unplugged for longer than twice the watchdog while not open, the hand
/// opens before it is plugged back in.
fn check_opens_on_link_loss(events: &[(Instant, HandEvent)], watchdog: Duration) -> usize {
    let mut state = HandState::Open;
    let mut waiting_to_open = false;
    let mut checked = 0;
    for (_, e) in events {
        match e {
            HandEvent::Preshape { .. } => state = HandState::Preshaped,
            HandEvent::Close { .. } => state = HandState::Closed,
            HandEvent::Open { .. } => state = HandState::Open,
            HandEvent::WatchdogOpen { .. } => {
                state = HandState::Open;
                waiting_to_open = false;
            }
            HandEvent::Unplugged {
                for_ms: Some(ms), ..
            } if Duration::from_millis(*ms) >= 2 * watchdog && state != HandState::Open => {
                waiting_to_open = true;
                checked += 1;
            }
            HandEvent::Replugged { .. } => {
                assert!(!waiting_to_open, "replugged still shaped: {events:?}");
            }
            _ => {}
        }
    }
    checked
}

struct CaseResult {
    approaches: Vec<Approach>,
    events: Vec<(Instant, HandEvent)>,
}

impl CaseResult {
    fn faults(&self, kind: FaultKind) -> usize {
        self.events
            .iter()
            .filter(|(_, e)| matches!(e, HandEvent::Fault { fault, .. } if *fault == kind))
            .count()
    }

    fn count(&self, pred: impl Fn(&HandEvent) -> bool) -> usize {
        self.events.iter().filter(|(_, e)| pred(e)).count()
    }

    fn commanded_under_faults(&self) -> usize {
        self.approaches[..APPROACHES]
            .iter()
            .filter(|a| a.report.preshape.is_some())
            .count()
    }
}

/// Connects cleanly, runs [`APPROACHES`] approaches under `spec`, ends the
/// faults and runs one more with a generous limit: it must be executed.
fn run_case(spec: &str) -> CaseResult {
    let dir = tempfile::tempdir().unwrap();
    let faults: FaultSpec = spec.parse().unwrap();
    let pty = PtyHand::plug_with_faults(&dir.path().join("hand"), faults, |_| {}).unwrap();
    pty.hand.set_faults(false);
    let hand = start_hand(pty.path(), link());
    pty.hand.set_faults(true);
    let mut approaches: Vec<Approach> = (0..APPROACHES)
        .map(|k| approach(&hand, Preshape::ALL[k % Preshape::ALL.len()], LIMIT))
        .collect();
    pty.hand.set_faults(false); // the fault ends
                                // Frames still held by a delay arrive; then heartbeats flow again.
    let beats = hand.stats().heartbeats;
    assert!(
        eventually(Duration::from_secs(60), || hand.stats().heartbeats
            >= beats + 3),
        "{spec}: heartbeats did not come back"
    );
    let last = approaches.last().unwrap().preshape;
    let next = *Preshape::ALL.iter().find(|p| **p != last).unwrap();
    approaches.push(approach(&hand, next, Duration::from_secs(30)));
    let recovery = &approaches[APPROACHES].report;
    assert!(
        recovery.preshape.is_some() && recovery.closure.is_some(),
        "{spec}: the link did not recover: {:?}",
        recovery.link_error
    );
    let events = pty.hand.timed_events();
    check_safety(&approaches, &events);
    CaseResult { approaches, events }
}

#[test]
fn dropped_frames_are_retransmitted_and_never_executed_late() {
    let r = run_case("drop=0.4,on=preshape+close,seed=1");
    assert!(r.faults(FaultKind::Drop) > 0);
    assert!(r.commanded_under_faults() > 0);
}

#[test]
fn corrupted_frames_are_refused_by_crc_and_retransmitted() {
    let r = run_case("corrupt=0.4,on=preshape+close,seed=2");
    assert!(r.faults(FaultKind::Corrupt) > 0);
    assert!(r.commanded_under_faults() > 0);
}

#[test]
fn duplicated_frames_are_executed_once() {
    let r = run_case("duplicate=0.6,on=preshape+close,seed=3");
    assert!(r.faults(FaultKind::Duplicate) > 0);
    assert!(r.count(|e| matches!(e, HandEvent::Duplicate { .. })) > 0);
    assert!(r.commanded_under_faults() > 0);
}

#[test]
fn frames_delayed_within_the_limit_are_executed_in_time() {
    let r = run_case("delay=0.5:100,on=preshape+close,seed=4");
    assert!(r.faults(FaultKind::Delay) > 0);
    assert!(r.commanded_under_faults() > 0);
}

#[test]
fn frames_delayed_past_the_limit_are_refused_by_the_hand() {
    // Seed 4 holds the first PRESHAPE 900 ms: every copy of it (the
    // retransmissions queue behind) reaches the hand after its deadline.
    let r = run_case("delay=0.5:900,on=preshape+close,seed=4");
    assert!(r.faults(FaultKind::Delay) > 0);
    let refused = r.count(|e| matches!(e, HandEvent::Expired { .. }));
    assert!(refused > 0, "{:?}", r.events);
    let first = &r.approaches[0].report;
    let expired = first.expired.as_ref().expect("the first decision expired");
    assert!(expired.transmissions > 0);
    assert!(first.closure.is_none());
}

#[test]
fn a_disconnect_opens_the_hand_and_the_link_comes_back() {
    let r = run_case("disconnect=0.3:700,on=preshape,seed=2");
    assert!(r.faults(FaultKind::Disconnect) > 0);
    let unplugged = r.count(|e| matches!(e, HandEvent::Unplugged { .. }));
    let replugged = r.count(|e| matches!(e, HandEvent::Replugged { .. }));
    assert!(unplugged > 0 && replugged == unplugged, "{:?}", r.events);
    check_opens_on_link_loss(&r.events, Duration::from_millis(link().watchdog_ms.into()));
}

#[test]
fn a_mix_of_every_fault_on_every_frame_stays_safe() {
    let r =
        run_case("drop=0.15,corrupt=0.15,duplicate=0.2,delay=0.1:500,disconnect=0.03:700,seed=7");
    for kind in [FaultKind::Drop, FaultKind::Corrupt, FaultKind::Duplicate] {
        assert!(r.faults(kind) > 0, "{kind:?}");
    }
    check_opens_on_link_loss(&r.events, Duration::from_millis(link().watchdog_ms.into()));
}

/// The case: the link goes down before the decision and comes back
/// after the decision is older than the limit. Before the age limit the
/// pre-shape was executed on reconnection, seconds late, and closed.
#[test]
fn a_decision_taken_while_the_link_is_down_is_never_executed_late() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), link());
    let generous = Duration::from_secs(30);
    let before = approach(&hand, Preshape::Power, generous);
    assert!(before.report.closure.is_some(), "shaped and closed");
    pty.hand.unplug();
    assert!(
        eventually(Duration::from_secs(10), || !hand.is_connected()),
        "the host noticed"
    );
    let stale = std::thread::scope(|s| {
        // Plugged back in once the decision is surely older than the limit
        // (a sleep lasts at least its duration).
        s.spawn(|| {
            std::thread::sleep(2 * LIMIT);
            pty.hand.replug();
        });
        approach(&hand, Preshape::Lateral, LIMIT)
    });
    let r = &stale.report;
    assert!(r.preshape.is_none() && r.closure.is_none(), "{r:?}");
    let expired = r.expired.as_ref().expect("reported as expired");
    assert_eq!(expired.preshape, Some(Preshape::Lateral));
    assert_eq!(expired.transmissions, 0, "never sent");
    let mut summary = SessionSummary::default();
    summary.record(1, r);
    assert_eq!((summary.expired, summary.exit_code()), (1, EXIT_EXPIRED));

    // The link recovers: the next decision is executed.
    let fresh = approach(&hand, Preshape::Pinch, generous);
    assert!(fresh.report.preshape.is_some() && fresh.report.closure.is_some());
    let events = pty.hand.timed_events();
    check_safety(&[before, stale, fresh], &events);
    let executed: Vec<_> = events
        .iter()
        .filter_map(|(_, e)| match e {
            HandEvent::Preshape { preshape, .. } => *preshape,
            _ => None,
        })
        .collect();
    assert_eq!(executed, vec![Preshape::Power, Preshape::Pinch]);
    // Closed when the link went down: the hand opened itself.
    let order: Vec<&str> = events
        .iter()
        .filter_map(|(_, e)| match e {
            HandEvent::Unplugged { .. } => Some("unplugged"),
            HandEvent::WatchdogOpen { .. } => Some("watchdog_open"),
            HandEvent::Replugged { .. } => Some("replugged"),
            _ => None,
        })
        .collect();
    assert_eq!(order, vec!["unplugged", "watchdog_open", "replugged"]);
}
