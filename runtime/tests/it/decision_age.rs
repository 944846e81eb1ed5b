//! What a decision's age counts: the time from the decision to the hand's
//! ACK, and nothing the frame source does after the decision.
//!
//! The replay of a 2.5 frames/s recording used to expire its pre-shape
//! unsent about 400 ms after the decision: ending the window joined the
//! capture thread, which was asleep in the paced source until the frame
//! after the window was due (one frame interval), and the decision's age
//! ran meanwhile. Here the source's wait is a gate, not a clock: the frame
//! after the window is held until the hand has executed the pre-shape (or,
//! if it never does, for [`HELD_AT_MOST`], far past the age limit). No
//! assertion is about how long anything took.

use crate::common::{fast_link, frames_of, start_hand, FakeModel};
use grasp_schema::taxonomy::{Class, Preshape};
use image::RgbImage;
use runtime::classifier::{ClassifyError, FrameClassifier};
use runtime::feed::FeedMode;
use runtime::policy::{Outcome, PolicyConfig};
use runtime::session::{ApproachResult, ReportLog, Session};
use runtime::simhand::{HandEvent, PtyHand};
use runtime::source::{Frame, FrameSource, MemorySource, Pacing, SourceError};
use runtime::trigger::Timer;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The recording's frame rate: frame 5 is at 2.0 s and ends the default
/// 2 s window; frame 6 (2.4 s) is the one the capture thread is fetching
/// when the decision is taken.
const FPS: f64 = 2.5;
/// Frames of the window plus the one that ends it.
const WINDOW_FRAMES: u64 = 6;
/// A bound for a stuck test; also how long the frame after the window is
/// held if the pre-shape never reaches the hand.
const HELD_AT_MOST: Duration = Duration::from_secs(8);
/// The age limit: generous so that a loaded machine cannot make the
/// pre-shape expire, yet far below [`HELD_AT_MOST`], so that a decision
/// waiting for the source expires as in the report.
const LIMIT_MS: u64 = 4000;

/// How the held frame was let go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Released {
    /// By the hand executing the pre-shape.
    ByThePreshape,
    /// By [`HELD_AT_MOST`] (or the hand's end): the pre-shape was not
    /// executed while it was held.
    Otherwise,
}

/// A recording whose frames after the window are fetched only once the
/// gate opens, like a paced replay sleeping until its next frame is due.
struct HeldAfterWindow {
    frames: MemorySource,
    next: u64,
    /// Told when the frame after the window is being fetched.
    holding: Sender<()>,
    gate: Receiver<()>,
    released: Arc<Mutex<Vec<Released>>>,
}

impl FrameSource for HeldAfterWindow {
    fn begin(&mut self) -> Result<(), SourceError> {
        self.next = 0;
        self.frames.begin()
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        if self.next >= WINDOW_FRAMES {
            let _ = self.holding.send(());
            let how = match self.gate.recv_timeout(HELD_AT_MOST) {
                Ok(()) => Released::ByThePreshape,
                Err(_) => Released::Otherwise,
            };
            self.released.lock().unwrap().push(how);
        }
        self.next += 1;
        self.frames.next_frame()
    }

    fn describe(&self) -> String {
        "recording held after its window".into()
    }
}

/// The fake model, which on the window's last voting frame waits until the
/// source holds the frame after the window: so the decision is always taken
/// while the capture thread is inside the source, the case of the report
/// (otherwise a race the capture thread usually wins).
struct WaitsForTheHold {
    model: FakeModel,
    calls: u64,
    holding: Receiver<()>,
}

impl FrameClassifier for WaitsForTheHold {
    fn classify(&mut self, frame: &RgbImage, time_s: f64) -> Result<[f32; 5], ClassifyError> {
        self.calls += 1;
        if self.calls == WINDOW_FRAMES - 1 {
            self.holding
                .recv_timeout(HELD_AT_MOST)
                .expect("the source fetches the frame after the window");
        }
        self.model.classify(frame, time_s)
    }
}

#[test]
fn a_decision_does_not_wait_for_the_frame_after_the_window() {
    let dir = tempfile::tempdir().unwrap();
    let (executed, gate) = std::sync::mpsc::channel();
    let pty = PtyHand::plug(&dir.path().join("hand"), move |e| {
        if matches!(e, HandEvent::Preshape { .. }) {
            let _ = executed.send(());
        }
    })
    .unwrap();
    let hand = start_hand(pty.path(), fast_link());
    let released = Arc::new(Mutex::new(Vec::new()));
    let (holding, held) = std::sync::mpsc::channel();
    let source = HeldAfterWindow {
        frames: MemorySource::new(frames_of(&[Class::Power; 8]), FPS, Pacing::AsFastAsPossible)
            .unwrap(),
        next: 0,
        holding,
        gate,
        released: released.clone(),
    };
    let policy = PolicyConfig {
        max_decision_age_ms: LIMIT_MS,
        ..PolicyConfig::default()
    };
    let stop = AtomicBool::new(false);
    let mut model = WaitsForTheHold {
        model: FakeModel::new(),
        calls: 0,
        holding: held,
    };
    let mut session = Session {
        hand: &hand,
        classifier: &mut model,
        policy: &policy,
        mode: FeedMode::Lockstep,
        stop: &stop,
    };
    let mut reports = ReportLog::default();
    let (_, summary) = session
        .run(
            Box::new(source),
            1,
            &mut Timer(Duration::ZERO),
            None,
            &mut reports,
        )
        .unwrap();

    let report = &reports.0[0];
    let d = &report.window.decision;
    assert_eq!(
        d.outcome,
        Outcome::Majority {
            preshape: Preshape::Power
        }
    );
    assert_eq!(d.frames, 5, "frames at 0, 0.4, ..., 1.6 s");
    assert!(
        report.expired.is_none(),
        "the decision expired: {:?}",
        report.expired
    );
    assert_eq!(ApproachResult::of(report), ApproachResult::Commanded);
    assert_eq!(summary.exit_code(), 0);
    // The hand executed the pre-shape while the source was still held in
    // the frame after the window.
    assert_eq!(*released.lock().unwrap(), vec![Released::ByThePreshape]);
    // The window's statistics end at the decision: the frame fetched after
    // it is neither captured nor dropped.
    assert_eq!(report.window.feed.captured, WINDOW_FRAMES);
    assert_eq!(report.window.feed.delivered, WINDOW_FRAMES);
    assert_eq!(report.window.feed.dropped, 0);
}
