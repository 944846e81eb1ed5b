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

use crate::common::{eventually, frames_of, start_hand, FakeModel};
use grasp_schema::taxonomy::{Class, Preshape};
use runtime::approach::{actuate, classify_window, ApproachReport, WindowReport};
use runtime::feed::FeedMode;
use runtime::link::{Hand, LinkConfig};
use runtime::policy::{Outcome, PolicyConfig};
use runtime::protocol::HandState;
use runtime::session::{SessionSummary, EXIT_EXPIRED, EXIT_HAND};
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

/// The window of an approach whose 12 frames all show `preshape`, decided
/// by the default policy; with its trigger time.
fn decided_window(preshape: Preshape) -> (Instant, WindowReport) {
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
    (t0, window)
}

fn approach(hand: &Hand, preshape: Preshape, limit: Duration) -> Approach {
    let (t0, window) = decided_window(preshape);
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

// ---- Failed, late and lost closures; a reconnect in every phase ----
//
// Whenever a PRESHAPE or CLOSE may have reached the hand and the approach
// does not end as decided, the host opens the hand; a CLOSE goes out only
// while the hand says (its last ACK, after a reconnect its HELLO) that it is
// in the decided pre-shape.

/// The hand's state after its last event (open before any).
fn final_state(events: &[(Instant, HandEvent)]) -> HandState {
    let mut state = HandState::Open;
    for (_, e) in events {
        match e {
            HandEvent::Preshape { .. } => state = HandState::Preshaped,
            HandEvent::Close { .. } => state = HandState::Closed,
            HandEvent::Open { .. } | HandEvent::WatchdogOpen { .. } => state = HandState::Open,
            _ => {}
        }
    }
    state
}

/// A closure trigger that runs `before` (unplug the hand, wait...) and
/// then fires.
struct ActingTrigger<F: FnMut() + Send> {
    before: F,
    fired: Option<Instant>,
}

impl<F: FnMut() + Send> Trigger for ActingTrigger<F> {
    fn wait(&mut self, _stop: &AtomicBool) -> Result<bool, TriggerError> {
        (self.before)();
        self.fired = Some(Instant::now());
        Ok(true)
    }

    fn describe(&self) -> String {
        "acting trigger".into()
    }
}

/// One approach deciding `preshape`, with `closure` as its closure trigger.
fn approach_with(
    hand: &Hand,
    preshape: Preshape,
    limit: Duration,
    closure: &mut dyn Trigger,
) -> ApproachReport {
    let (t0, window) = decided_window(preshape);
    let stop = AtomicBool::new(false);
    actuate(hand, window, Some(closure), &stop, t0, limit).unwrap()
}

/// One approach under `spec` (faults on after a clean HELLO): its report,
/// the hand's log and the run's exit code for it.
fn closure_case(spec: &str, limit: Duration) -> (ApproachReport, Vec<(Instant, HandEvent)>, u8) {
    let dir = tempfile::tempdir().unwrap();
    let faults: FaultSpec = spec.parse().unwrap();
    let pty = PtyHand::plug_with_faults(&dir.path().join("hand"), faults, |_| {}).unwrap();
    pty.hand.set_faults(false);
    let hand = start_hand(pty.path(), link());
    pty.hand.set_faults(true);
    let mut closure = runtime::trigger::Timer(Duration::from_millis(20));
    let report = approach_with(&hand, Preshape::Pinch3, limit, &mut closure);
    // Frames a delay still holds arrive before the log is read.
    std::thread::sleep(Duration::from_millis(600));
    let mut summary = SessionSummary::default();
    summary.record(1, &report);
    (report, pty.hand.timed_events(), summary.exit_code())
}

/// The hand was opened by the host after the failed closure, and the run
/// fails with `code`.
fn assert_opened_after_failed_closure(
    spec: &str,
    report: &ApproachReport,
    events: &[(Instant, HandEvent)],
    code: u8,
    expected_code: u8,
) {
    assert!(
        report.preshape.is_some(),
        "{spec}: pre-shaped first: {report:?}"
    );
    assert!(report.closure.is_none(), "{spec}: {report:?}");
    let open = report.reopened.as_ref().unwrap_or_else(|| {
        panic!("{spec}: no OPEN after the failed closure: {report:?} {events:?}")
    });
    assert_eq!(open.hand_state, HandState::Open, "{spec}");
    assert_eq!(final_state(events), HandState::Open, "{spec}: {events:?}");
    let last = report
        .hand
        .as_ref()
        .expect("the hand's last ACK is reported");
    assert_eq!(
        (last.command.as_str(), last.state),
        ("OPEN", HandState::Open)
    );
    assert_eq!(code, expected_code, "{spec}: {report:?}");
}

#[test]
fn a_late_closure_executed_by_the_hand_is_followed_by_an_open() {
    // Every CLOSE and its ACK are held 200 ms: the hand closes in time,
    // its ACK comes after the 300 ms limit. The host cannot know it closed.
    let spec = "delay=1:200,on=close";
    let (report, events, code) = closure_case(spec, LIMIT);
    let expired = report.expired.as_ref().expect("the closure expired");
    assert_eq!(expired.command, "CLOSE");
    assert!(expired.transmissions > 0);
    assert!(events
        .iter()
        .any(|(_, e)| matches!(e, HandEvent::Close { .. })));
    assert_opened_after_failed_closure(spec, &report, &events, code, EXIT_EXPIRED);
    let mut summary = SessionSummary::default();
    summary.record(1, &report);
    let reason = summary.failure_message().unwrap();
    assert!(
        reason.contains("may have reached the hand") && reason.ends_with("hand opened"),
        "{reason}"
    );
}

#[test]
fn a_lost_or_corrupted_closure_is_followed_by_an_open() {
    for spec in ["drop=1,on=close", "corrupt=1,on=close"] {
        // The limit lets every retry run out: the link reports no ACK.
        let (report, events, code) = closure_case(spec, Duration::from_secs(30));
        assert!(report.link_error.is_some(), "{spec}: {report:?}");
        assert!(!events
            .iter()
            .any(|(_, e)| matches!(e, HandEvent::Close { .. })));
        assert_opened_after_failed_closure(spec, &report, &events, code, EXIT_HAND);
    }
    // With the default limit, the same loss ends in an expired closure.
    let spec = "drop=1,on=close";
    let (report, events, code) = closure_case(spec, LIMIT);
    assert!(report.expired.is_some(), "{report:?}");
    assert_opened_after_failed_closure(spec, &report, &events, code, EXIT_EXPIRED);
}

#[test]
fn a_closure_past_a_one_millisecond_limit_is_followed_by_an_open() {
    // Whatever got through in 1 ms: never left pre-shaped by a failed
    // approach.
    let (report, events, _) = closure_case("delay=1:5,on=preshape+close", Duration::from_millis(1));
    if report.preshape.is_some() {
        assert!(report.reopened.is_some(), "{report:?}");
    }
    assert_eq!(final_state(&events), HandState::Open, "{events:?}");
}

#[test]
fn the_closure_trigger_ending_opens_the_hand_and_fails_the_approach() {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), link());
    let (tx, mut closure) = runtime::trigger::ChannelTrigger::new("stdin (press Enter)");
    drop(tx); // end of input: it can never fire
    let report = approach_with(&hand, Preshape::Lateral, LIMIT, &mut closure);
    assert!(report.preshape.is_some() && report.closure.is_none());
    assert!(report.closure_missed.is_some(), "{report:?}");
    assert!(report.reopened.is_some(), "{report:?}");
    assert_eq!(final_state(&pty.hand.timed_events()), HandState::Open);
    let mut summary = SessionSummary::default();
    summary.record(1, &report);
    assert_eq!(summary.commanded, 0);
    assert_eq!(summary.exit_code(), runtime::session::EXIT_ABORTED);
    let reason = summary.failure_message().unwrap();
    assert!(reason.contains("ended before it fired"), "{reason}");
}

/// The hand unplugged during the closure delay for `outage`; `opens`: the
/// watchdog opens it meanwhile (the outage is longer than the watchdog).
fn reconnect_in_closure_delay(outage: Duration, opens: bool) {
    let dir = tempfile::tempdir().unwrap();
    let pty = PtyHand::plug(&dir.path().join("hand"), |_| {}).unwrap();
    let hand = start_hand(pty.path(), link());
    let mut closure = ActingTrigger {
        before: || {
            pty.hand.unplug();
            assert!(eventually(Duration::from_secs(10), || !hand.is_connected()));
            std::thread::sleep(outage);
            if opens {
                assert!(eventually(Duration::from_secs(10), || pty
                    .hand
                    .events()
                    .iter()
                    .any(|e| matches!(e, HandEvent::WatchdogOpen { .. }))));
            }
            pty.hand.replug();
            assert!(eventually(Duration::from_secs(10), || hand.is_connected()));
        },
        fired: None,
    };
    let report = approach_with(
        &hand,
        Preshape::Pinch3,
        Duration::from_secs(30),
        &mut closure,
    );
    let events = pty.hand.timed_events();
    let hello_after = events
        .iter()
        .rposition(|(_, e)| matches!(e, HandEvent::Hello { .. }))
        .unwrap();
    let closed_after = events[hello_after..]
        .iter()
        .any(|(_, e)| matches!(e, HandEvent::Close { .. }));
    if opens {
        assert!(!closed_after, "closed a hand that was open: {events:?}");
        assert!(
            report.closure.is_none() && report.reopened.is_some(),
            "{report:?}"
        );
        let error = report.link_error.as_deref().unwrap();
        assert!(error.contains("not pre-shaped"), "{error}");
        let mut summary = SessionSummary::default();
        summary.record(1, &report);
        assert_eq!(summary.exit_code(), runtime::session::EXIT_HAND);
        assert!(summary.failure_message().unwrap().ends_with("hand opened"));
    } else {
        // Still in the decided pre-shape, as its HELLO said: closed.
        assert!(
            closed_after && report.closure.is_some(),
            "{report:?} {events:?}"
        );
        assert_eq!(report.hand.as_ref().unwrap().state, HandState::Closed);
    }
}

#[test]
fn after_a_reconnect_in_the_closure_delay_an_opened_hand_is_not_closed() {
    reconnect_in_closure_delay(Duration::from_millis(900), true);
}

#[test]
fn after_a_short_reconnect_in_the_closure_delay_a_shaped_hand_is_closed() {
    reconnect_in_closure_delay(Duration::ZERO, false);
}

#[test]
fn a_fresh_hand_on_the_same_path_is_never_closed() {
    // The hand is replaced during the closure delay: the new one is open in
    // its Power configuration, not in the decided pinch3.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hand");
    let first = PtyHand::plug(&path, |_| {}).unwrap();
    let hand = start_hand(first.path(), link());
    let mut first = Some(first);
    let second = std::sync::Mutex::new(None);
    let mut closure = ActingTrigger {
        before: || {
            drop(first.take());
            assert!(eventually(Duration::from_secs(10), || !hand.is_connected()));
            *second.lock().unwrap() = Some(PtyHand::plug(&path, |_| {}).unwrap());
            assert!(eventually(Duration::from_secs(10), || hand.is_connected()));
        },
        fired: None,
    };
    let report = approach_with(
        &hand,
        Preshape::Pinch3,
        Duration::from_secs(30),
        &mut closure,
    );
    let second = second.lock().unwrap().take().unwrap();
    let events = second.hand.events();
    assert!(
        !events.iter().any(|e| matches!(e, HandEvent::Close { .. })),
        "{events:?}"
    );
    assert!(
        report.closure.is_none() && report.link_error.is_some(),
        "{report:?}"
    );
    let last = report.hand.as_ref().unwrap();
    assert_eq!(last.state, HandState::Open);
}

#[test]
fn a_reconnect_while_the_closure_is_in_flight_never_closes_an_opened_hand() {
    // The hand unplugs itself on the CLOSE for longer than its watchdog:
    // whether or not it executed the CLOSE, the watchdog opens it, its
    // HELLO says open, and the CLOSE is not sent again.
    let spec = "disconnect=1:900,on=close";
    let (report, events, code) = closure_case(spec, Duration::from_secs(30));
    let hello = events
        .iter()
        .rposition(|(_, e)| matches!(e, HandEvent::Hello { .. }))
        .unwrap();
    assert!(
        !events[hello..]
            .iter()
            .any(|(_, e)| matches!(e, HandEvent::Close { .. })),
        "{events:?}"
    );
    assert_opened_after_failed_closure(spec, &report, &events, code, EXIT_HAND);
}

#[test]
fn a_reconnect_while_the_preshape_is_in_flight_executes_it_once_shaped() {
    // The hand unplugs itself on the PRESHAPE: the host re-opens, says HELLO
    // and sends the pre-shape again; the closure follows only on the shaped
    // hand.
    let (report, events, code) = closure_case(
        "disconnect=1:200,on=preshape,until=3000",
        Duration::from_secs(30),
    );
    let _ = code;
    check_safety_single(&report, &events);
}

/// One approach's report against the hand's log: a CLOSE only after a
/// PRESHAPE of the decided pinch3, and the hand open unless the closure
/// was confirmed.
fn check_safety_single(report: &ApproachReport, events: &[(Instant, HandEvent)]) {
    let mut shaped = false;
    for (_, e) in events {
        match e {
            HandEvent::Preshape { preshape, .. } => {
                assert_eq!(*preshape, Some(Preshape::Pinch3));
                shaped = true;
            }
            HandEvent::WatchdogOpen { .. } | HandEvent::Open { .. } => shaped = false,
            HandEvent::Close { .. } => assert!(shaped, "closed unshaped: {events:?}"),
            _ => {}
        }
    }
    if report.closure.is_none() {
        assert_eq!(
            final_state(events),
            HandState::Open,
            "{report:?} {events:?}"
        );
    }
}
