//! The `hannes-run run` loop: approach after approach (trigger, window,
//! decision, pre-shape, closure) until the count is reached, the source
//! ends or a stop is requested, and what the run as a whole amounts to:
//! every approach's result, counted, and the exit code of the first failed
//! one.
//!
//! | exit code | meaning |
//! |---|---|
//! | 0 | every approach ended as decided (a pre-shape executed, or no command on a weak vote without fallback) |
//! | 1 | an error outside the approaches (arguments, config, checkpoint, source, report file) |
//! | 2 | a command-line usage error |
//! | 3 ([`EXIT_ABORTED`]) | an approach was aborted: the frame source or the classifier failed, the model output was invalid, or the closure trigger ended before it fired (the hand opened) |
//! | 4 ([`EXIT_HAND`]) | the hand could not be reached or did not acknowledge a command |
//! | 5 ([`EXIT_EXPIRED`]) | a decision (or closure) became older than its age limit before the hand acknowledged it: not executed |
//! | 128 + N ([`Signal::exit_code`]: 130 SIGINT, 143 SIGTERM, 129 SIGHUP) | stopped by signal N: during an approach (nothing sent after it; the hand opened if a command may have reached it) or between approaches |
//!
//! A stop counts as a failure at the point it came: with an earlier failed
//! approach, the code is that approach's.

use crate::approach::{actuate, classify_window_until, ApproachReport, FramePrediction};
use crate::classifier::FrameClassifier;
use crate::feed::FeedMode;
use crate::link::{Hand, StartError};
use crate::policy::{Outcome, PolicyConfig};
use crate::signals::Signal;
use crate::source::{FrameSource, SourceError};
use crate::trigger::{Trigger, TriggerError};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

pub const EXIT_ABORTED: u8 = 3;
pub const EXIT_HAND: u8 = 4;
pub const EXIT_EXPIRED: u8 = 5;
/// The code of a stop whose signal is unknown (the flag set otherwise):
/// SIGINT's.
pub const EXIT_STOPPED: u8 = 128 + libc::SIGINT as u8;

/// The exit code of a stop by `signal`.
pub fn exit_code_of_stop(signal: Option<Signal>) -> u8 {
    signal.map_or(EXIT_STOPPED, Signal::exit_code)
}

fn stopped_by(signal: Option<Signal>) -> String {
    match signal {
        Some(s) => format!("stopped by {s}"),
        None => "stopped on request".into(),
    }
}

/// The exit code of a link that did not start, before any approach:
/// [`EXIT_HAND`] if the hand could not be reached, else 1 (a setting).
pub fn exit_code_before_approaches(e: &StartError) -> u8 {
    match e {
        StartError::Link(_) => EXIT_HAND,
        StartError::Config(_) | StartError::Heartbeat(_) => 1,
    }
}

/// How one approach ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ApproachResult {
    /// The pre-shape (and closure, if any) was acknowledged.
    Commanded,
    /// A weak vote without fallback: nothing to send, by design.
    NoCommand,
    /// Frame source or classifier failure, or an invalid model output.
    Aborted,
    /// The decision or the closure was too old to execute.
    Expired,
    /// The hand could not be reached or did not acknowledge.
    HandFailed,
    /// A stop (a signal) ended the approach before it was done.
    Stopped,
}

impl ApproachResult {
    pub fn of(report: &ApproachReport) -> Self {
        // The stop first: whatever else went wrong, it is why the approach
        // ended where it did.
        if report.stopped.is_some() {
            ApproachResult::Stopped
        } else if matches!(report.window.decision.outcome, Outcome::Aborted { .. }) {
            ApproachResult::Aborted
        } else if report.expired.is_some() {
            ApproachResult::Expired
        } else if report.link_error.is_some() {
            ApproachResult::HandFailed
        } else if report.closure_missed.is_some() {
            ApproachResult::Aborted
        } else if report.preshape.is_some() {
            ApproachResult::Commanded
        } else {
            ApproachResult::NoCommand
        }
    }

    /// The run's exit code if this approach is its first failure.
    pub fn exit_code(self, report: &ApproachReport) -> Option<u8> {
        match self {
            ApproachResult::Commanded | ApproachResult::NoCommand => None,
            ApproachResult::Aborted => Some(EXIT_ABORTED),
            ApproachResult::HandFailed => Some(EXIT_HAND),
            ApproachResult::Expired => Some(EXIT_EXPIRED),
            ApproachResult::Stopped => Some(exit_code_of_stop(report.stopped.as_ref()?.signal)),
        }
    }
}

/// One line saying why approach `n` failed.
pub fn failure_reason(approach: usize, report: &ApproachReport) -> String {
    match ApproachResult::of(report) {
        ApproachResult::Aborted => match &report.closure_missed {
            Some(why) => format!("approach {approach}: {why}; {}", hand_after(report)),
            None => format!("approach {approach}: {}", report.window.decision.outcome),
        },
        ApproachResult::Expired => {
            let e = report.expired.as_ref().expect("expired");
            let what = match e.preshape {
                Some(p) => format!("the {p} pre-shape"),
                None => format!("the {}", e.command),
            };
            let sent = match (e.refused_by_hand, e.transmissions) {
                (true, _) => ", the hand refused a late copy".to_string(),
                (false, 0) => ", never sent".to_string(),
                (false, n) => format!(", {n} copies sent: it may have reached the hand"),
            };
            let end = match (e.command, &report.reopened) {
                ("CLOSE", _) | (_, Some(_)) => format!("no closure; {}", hand_after(report)),
                _ => "not executed, no closure".to_string(),
            };
            format!(
                "approach {approach}: {what} was not acknowledged within its {:.0} ms age limit \
                 (given up at {:.0} ms{sent}): {end}",
                e.limit_ms, e.age_ms
            )
        }
        ApproachResult::HandFailed => {
            let error = report.link_error.as_deref().unwrap_or("link failure");
            match (&report.reopened, report.preshape.is_some()) {
                (Some(_), _) => format!(
                    "approach {approach}: the hand was not commanded as decided: {error}; hand opened"
                ),
                (None, true) => format!(
                    "approach {approach}: the closure failed: {error}; \
                     the hand could not be opened, its watchdog opens it"
                ),
                (None, false) => {
                    format!("approach {approach}: the hand was not commanded: {error}")
                }
            }
        }
        ApproachResult::Stopped => {
            let stop = report.stopped.as_ref().expect("stopped");
            let hand = match (stop.may_have_moved, &report.reopened) {
                (false, _) => "nothing was sent to the hand".to_string(),
                (true, Some(_)) => "hand opened".to_string(),
                (true, None) => format!(
                    "the hand could not be opened ({}); its watchdog opens it",
                    report.link_error.as_deref().unwrap_or("link failure")
                ),
            };
            format!(
                "approach {approach}: {} {}: {hand}",
                stopped_by(stop.signal),
                stop.phase
            )
        }
        ApproachResult::Commanded | ApproachResult::NoCommand => format!("approach {approach}: ok"),
    }
}

/// What became of the hand after a failed approach that opens it.
fn hand_after(report: &ApproachReport) -> String {
    match &report.reopened {
        Some(_) => "hand opened".to_string(),
        None => format!(
            "the hand could not be opened ({}); its watchdog opens it",
            report.link_error.as_deref().unwrap_or("link failure")
        ),
    }
}

/// The first failed approach of a run.
#[derive(Debug, Clone, Serialize)]
pub struct SessionFailure {
    pub approach: usize,
    /// `None`: a stop between approaches.
    pub result: Option<ApproachResult>,
    pub reason: String,
    pub exit_code: u8,
}

/// What a run amounted to.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SessionSummary {
    pub approaches: usize,
    pub commanded: usize,
    pub no_command: usize,
    pub aborted: usize,
    /// Decisions (or closures) dropped as too old.
    pub expired: usize,
    pub hand_failures: usize,
    /// Approaches ended by a stop (a signal).
    pub stopped: usize,
    /// A stop came between approaches (while waiting for a trigger, or
    /// after an approach had ended).
    pub stopped_between: bool,
    pub first_failure: Option<SessionFailure>,
}

impl SessionSummary {
    pub fn record(&mut self, n: usize, report: &ApproachReport) {
        self.approaches += 1;
        let result = ApproachResult::of(report);
        match result {
            ApproachResult::Commanded => self.commanded += 1,
            ApproachResult::NoCommand => self.no_command += 1,
            ApproachResult::Aborted => self.aborted += 1,
            ApproachResult::Expired => self.expired += 1,
            ApproachResult::HandFailed => self.hand_failures += 1,
            ApproachResult::Stopped => self.stopped += 1,
        }
        if let (Some(code), None) = (result.exit_code(report), &self.first_failure) {
            self.first_failure = Some(SessionFailure {
                approach: n,
                result: Some(result),
                reason: failure_reason(n, report),
                exit_code: code,
            });
        }
    }

    /// A stop by `signal` outside an approach: `waiting` for the trigger
    /// of approach `n`, or after approach `n` ended.
    pub fn record_stop_between(&mut self, n: usize, waiting: bool, signal: Option<Signal>) {
        self.stopped_between = true;
        if self.first_failure.is_some() {
            return;
        }
        let when = match waiting {
            true => format!("while waiting for the trigger of approach {n}"),
            false => format!("after approach {n} ended"),
        };
        self.first_failure = Some(SessionFailure {
            approach: n,
            result: None,
            reason: format!("{} {when}: no command in flight", stopped_by(signal)),
            exit_code: exit_code_of_stop(signal),
        });
    }

    pub fn failures(&self) -> usize {
        self.aborted + self.expired + self.hand_failures + self.stopped
    }

    /// 0, or the code of the first failure (an approach, or a stop).
    pub fn exit_code(&self) -> u8 {
        self.first_failure.as_ref().map_or(0, |f| f.exit_code)
    }

    /// The one-line reason of a failed run.
    pub fn failure_message(&self) -> Option<String> {
        let first = self.first_failure.as_ref()?;
        // A stop between approaches is a failure but not an approach's.
        let more = self
            .failures()
            .saturating_sub(usize::from(first.result.is_some()));
        Some(match more {
            0 => first.reason.clone(),
            _ => format!(
                "{} (and {more} more of {} approaches failed)",
                first.reason, self.approaches
            ),
        })
    }

    /// One line of counts.
    pub fn describe(&self) -> String {
        format!(
            "{} approach{}: {} commanded, {} without command, {} aborted, {} expired \
             (stale decision), {} hand failures, {} stopped",
            self.approaches,
            if self.approaches == 1 { "" } else { "es" },
            self.commanded,
            self.no_command,
            self.aborted,
            self.expired,
            self.hand_failures,
            self.stopped
        )
    }
}

/// Why a run ended before its approaches did (an approach's own failure
/// is its outcome, not an error).
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The trigger failed.
    #[error(transparent)]
    Trigger(#[from] TriggerError),
    /// The frame feed did not start.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// An observer could not record an approach.
    #[error(transparent)]
    Report(#[from] ReportError),
}

/// A report file that cannot be written (`doing`: open or write).
#[derive(Debug, thiserror::Error)]
#[error("cannot {doing} report {}", path.display())]
pub struct ReportError {
    pub doing: &'static str,
    pub path: PathBuf,
    #[source]
    pub source: std::io::Error,
}

/// Sees a run's progress (the CLI prints it).
pub trait SessionObserver {
    fn waiting(&mut self, _approach: usize, _trigger: &str) {}
    /// The trigger fired: the approach window starts.
    fn triggered(&mut self, _approach: usize) {}
    fn frame(&mut self, _prediction: &FramePrediction) {}
    fn approach(&mut self, _approach: usize, _report: &ApproachReport) -> Result<(), ReportError> {
        Ok(())
    }
}

/// An observer that keeps every approach's report, in order (tests, tools).
#[derive(Debug, Default)]
pub struct ReportLog(pub Vec<ApproachReport>);

impl SessionObserver for ReportLog {
    fn approach(&mut self, _approach: usize, report: &ApproachReport) -> Result<(), ReportError> {
        self.0.push(report.clone());
        Ok(())
    }
}

/// Everything an approach needs besides its frames and triggers.
pub struct Session<'a> {
    pub hand: &'a Hand,
    pub classifier: &'a mut dyn FrameClassifier,
    pub policy: &'a PolicyConfig,
    pub mode: FeedMode,
    pub stop: &'a AtomicBool,
}

impl Session<'_> {
    /// Runs up to `approaches` approaches from `source`; returns the source
    /// and the summary. Errors only for what is not an approach's outcome
    /// (a trigger that fails, an observer's error).
    pub fn run(
        &mut self,
        mut source: Box<dyn FrameSource>,
        approaches: usize,
        trigger: &mut dyn Trigger,
        mut closure: Option<&mut dyn Trigger>,
        observer: &mut dyn SessionObserver,
    ) -> Result<(Box<dyn FrameSource>, SessionSummary), SessionError> {
        let mut summary = SessionSummary::default();
        for n in 1..=approaches {
            observer.waiting(n, &trigger.describe());
            if !trigger.wait(self.stop)? {
                if self.stop_requested() {
                    summary.record_stop_between(n, true, crate::signals::received());
                }
                break;
            }
            let t0 = Instant::now();
            observer.triggered(n);
            let (feed, window) = classify_window_until(
                source,
                self.mode,
                &mut *self.classifier,
                self.policy,
                t0,
                self.stop,
                &mut |p| observer.frame(p),
            )?;
            let closure: Option<&mut dyn Trigger> = match &mut closure {
                Some(c) => Some(&mut **c),
                None => None,
            };
            let max_age = self.policy.max_decision_age();
            let report = actuate(self.hand, window, closure, self.stop, t0, max_age)?;
            // Only now: the capture thread may have been inside the source
            // (a replay sleeping until its next frame is due) since the
            // decision, whose age must not wait for it.
            source = feed.join();
            summary.record(n, &report);
            observer.approach(n, &report)?;
            if self.stop_requested() {
                if report.stopped.is_none() && n < approaches {
                    summary.record_stop_between(n, false, crate::signals::received());
                }
                break;
            }
        }
        Ok((source, summary))
    }

    fn stop_requested(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}
