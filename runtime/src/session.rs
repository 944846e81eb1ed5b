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
//! | 3 ([`EXIT_ABORTED`]) | an approach was aborted: the frame source or the classifier failed, or the model output was invalid |
//! | 4 ([`EXIT_HAND`]) | the hand could not be reached or did not acknowledge a command |
//! | 5 ([`EXIT_EXPIRED`]) | a decision (or closure) became older than its age limit before the hand acknowledged it: not executed |

use crate::approach::{actuate, classify_window, ApproachReport, FramePrediction};
use crate::classifier::FrameClassifier;
use crate::feed::FeedMode;
use crate::link::{Hand, LinkError};
use crate::policy::{Outcome, PolicyConfig};
use crate::source::FrameSource;
use crate::trigger::Trigger;
use anyhow::Result;
use serde::Serialize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

pub const EXIT_ABORTED: u8 = 3;
pub const EXIT_HAND: u8 = 4;
pub const EXIT_EXPIRED: u8 = 5;

/// The exit code of an error that stopped `run` before any approach:
/// [`EXIT_HAND`] if the hand could not be reached, else 1.
pub fn exit_code_before_approaches(e: &anyhow::Error) -> u8 {
    match e.chain().any(|c| c.downcast_ref::<LinkError>().is_some()) {
        true => EXIT_HAND,
        false => 1,
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
}

impl ApproachResult {
    pub fn of(report: &ApproachReport) -> Self {
        if matches!(report.window.decision.outcome, Outcome::Aborted { .. }) {
            ApproachResult::Aborted
        } else if report.expired.is_some() {
            ApproachResult::Expired
        } else if report.link_error.is_some() {
            ApproachResult::HandFailed
        } else if report.preshape.is_some() {
            ApproachResult::Commanded
        } else {
            ApproachResult::NoCommand
        }
    }

    /// The run's exit code if this approach is its first failure.
    pub fn exit_code(self) -> Option<u8> {
        match self {
            ApproachResult::Commanded | ApproachResult::NoCommand => None,
            ApproachResult::Aborted => Some(EXIT_ABORTED),
            ApproachResult::HandFailed => Some(EXIT_HAND),
            ApproachResult::Expired => Some(EXIT_EXPIRED),
        }
    }
}

/// One line saying why approach `n` failed.
pub fn failure_reason(approach: usize, report: &ApproachReport) -> String {
    match ApproachResult::of(report) {
        ApproachResult::Aborted => {
            format!("approach {approach}: {}", report.window.decision.outcome)
        }
        ApproachResult::Expired => {
            let e = report.expired.as_ref().expect("expired");
            let what = match e.preshape {
                Some(p) => format!("the {p} pre-shape"),
                None => format!("the {}", e.command),
            };
            let refused = match e.refused_by_hand {
                true => ", the hand refused a late copy",
                false => "",
            };
            format!(
                "approach {approach}: {what} was not acknowledged within its {:.0} ms age limit \
                 (given up at {:.0} ms{refused}): not executed, no closure",
                e.limit_ms, e.age_ms
            )
        }
        ApproachResult::HandFailed => format!(
            "approach {approach}: the hand was not commanded: {}",
            report.link_error.as_deref().unwrap_or("link failure")
        ),
        ApproachResult::Commanded | ApproachResult::NoCommand => format!("approach {approach}: ok"),
    }
}

/// The first failed approach of a run.
#[derive(Debug, Clone, Serialize)]
pub struct SessionFailure {
    pub approach: usize,
    pub result: ApproachResult,
    pub reason: String,
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
        }
        if result.exit_code().is_some() && self.first_failure.is_none() {
            self.first_failure = Some(SessionFailure {
                approach: n,
                result,
                reason: failure_reason(n, report),
            });
        }
    }

    pub fn failures(&self) -> usize {
        self.aborted + self.expired + self.hand_failures
    }

    /// 0, or the code of the first failed approach.
    pub fn exit_code(&self) -> u8 {
        self.first_failure
            .as_ref()
            .and_then(|f| f.result.exit_code())
            .unwrap_or(0)
    }

    /// The one-line reason of a failed run.
    pub fn failure_message(&self) -> Option<String> {
        let first = self.first_failure.as_ref()?;
        let more = self.failures() - 1;
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
             (stale decision), {} hand failures",
            self.approaches,
            if self.approaches == 1 { "" } else { "es" },
            self.commanded,
            self.no_command,
            self.aborted,
            self.expired,
            self.hand_failures
        )
    }
}

/// Sees a run's progress (the CLI prints it).
pub trait SessionObserver {
    fn waiting(&mut self, _approach: usize, _trigger: &str) {}
    fn frame(&mut self, _prediction: &FramePrediction) {}
    fn approach(&mut self, _approach: usize, _report: &ApproachReport) -> Result<()> {
        Ok(())
    }
}

/// An observer that keeps every approach's report, in order (tests, tools).
#[derive(Debug, Default)]
pub struct ReportLog(pub Vec<ApproachReport>);

impl SessionObserver for ReportLog {
    fn approach(&mut self, _approach: usize, report: &ApproachReport) -> Result<()> {
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
    ) -> Result<(Box<dyn FrameSource>, SessionSummary)> {
        let mut summary = SessionSummary::default();
        for n in 1..=approaches {
            observer.waiting(n, &trigger.describe());
            if !trigger.wait(self.stop)? {
                break;
            }
            let t0 = Instant::now();
            let (feed, window) = classify_window(
                source,
                self.mode,
                &mut *self.classifier,
                self.policy,
                t0,
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
            if self.stop.load(Ordering::Relaxed) {
                break;
            }
        }
        Ok((source, summary))
    }
}
