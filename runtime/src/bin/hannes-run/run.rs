//! `hannes-run run`: approach after approach against the hand, each
//! printed and appended to the report file.

use crate::args::RunArgs;
use crate::setup::{config, open_source, stop_flag};
use crate::table::votes;
use anyhow::Result;
use grasp_main::Failure;
use runtime::approach::{ApproachReport, FramePrediction};
use runtime::feed::FeedMode;
use runtime::link::{Hand, HandLink, LinkConfig};
use runtime::session::{ApproachResult, ReportError, Session, SessionObserver};
use runtime::source::Pacing;
use runtime::transport::SerialConnector;
use runtime::trigger::{parse_trigger, Trigger};
use std::io::Write;
use std::path::Path;

pub(crate) fn run(args: RunArgs) -> Result<()> {
    let cfg = config(&args.policy)?;
    let stop = stop_flag()?;
    let mut classifier = runtime::model::load(&args.source.checkpoint)?;
    let pacing = if args.as_fast {
        Pacing::AsFastAsPossible
    } else {
        Pacing::RealTime
    };
    let (source, live) = open_source(&args.source, pacing, &mut classifier)?;
    let mode = if args.as_fast && !live {
        FeedMode::Lockstep
    } else {
        FeedMode::Latest
    };
    let mut triggers = triggers(&args)?;
    let hand = start_hand(&args, cfg.link.clone())?;
    let approaches = args.approaches.unwrap_or(if live { usize::MAX } else { 1 });
    let model = runtime::model::ModelRecord::of(
        &classifier,
        &args.source.checkpoint,
        args.source.lens.given(),
    );
    let mut session = Session {
        hand: &hand,
        classifier: &mut classifier,
        policy: &cfg.policy,
        mode,
        stop,
    };
    let mut printer = RunPrinter {
        report: args.report.as_deref(),
        model,
    };
    let closure = triggers
        .closure
        .as_mut()
        .map(|c| c.as_mut() as &mut dyn Trigger);
    let trigger = triggers.start.as_mut();
    let (_, summary) = session.run(source, approaches, trigger, closure, &mut printer)?;
    print_link_stats(&hand);
    eprintln!("{}", summary.describe());
    match summary.failure_message() {
        Some(reason) => Err(Failure::new(summary.exit_code(), reason).into()),
        None => Ok(()),
    }
}

/// What starts an approach, and what closes the fingers after its
/// pre-shape (`--closure none`: nothing).
struct Triggers {
    start: Box<dyn Trigger>,
    closure: Option<Box<dyn Trigger>>,
}

/// The run's triggers; given `stdin` both ways, they share one reader.
fn triggers(args: &RunArgs) -> Result<Triggers> {
    let mut stdin = None;
    let trigger = parse_trigger(&args.trigger, &mut stdin)?;
    let closure = match args.closure.as_str() {
        "none" => None,
        spec => Some(parse_trigger(spec, &mut stdin)?),
    };
    Ok(Triggers {
        start: trigger,
        closure,
    })
}

/// Connects to the hand. An unreachable hand exits with its own code, not
/// the 1 of the other errors before the first approach.
fn start_hand(args: &RunArgs, cfg: LinkConfig) -> Result<Hand> {
    let link = HandLink::new(Box::new(SerialConnector::new(&args.port, args.baud)), cfg);
    match Hand::start(link) {
        Ok(hand) => Ok(hand),
        Err(e) => {
            let code = runtime::session::exit_code_before_approaches(&e);
            Err(anyhow::Error::new(e)
                .context(Failure::new(code, "cannot start the link to the hand")))
        }
    }
}

fn print_link_stats(hand: &Hand) {
    let stats = hand.stats();
    eprintln!(
        "link: {} transmissions, {} retransmissions, {} heartbeats, {} reconnects, {} CRC errors",
        stats.transmissions,
        stats.retransmissions,
        stats.heartbeats,
        stats.reconnects,
        stats.rx_crc_errors
    );
}

/// One line of `--report`: the approach's report with its number and result.
#[derive(serde::Serialize)]
struct ReportLine<'a> {
    approach: usize,
    result: ApproachResult,
    model: &'a runtime::model::ModelRecord,
    #[serde(flatten)]
    report: &'a ApproachReport,
}

/// Prints each approach and appends it to the report file.
struct RunPrinter<'a> {
    report: Option<&'a Path>,
    model: runtime::model::ModelRecord,
}

impl SessionObserver for RunPrinter<'_> {
    fn waiting(&mut self, approach: usize, trigger: &str) {
        eprintln!("approach {approach}: waiting for trigger ({trigger})");
    }

    fn triggered(&mut self, approach: usize) {
        eprintln!("approach {approach}: triggered, classifying the approach window");
    }

    fn frame(&mut self, p: &FramePrediction) {
        tracing::debug!(frame = p.index, class = ?p.class, "classified");
    }

    fn approach(&mut self, n: usize, report: &ApproachReport) -> Result<(), ReportError> {
        let d = &report.window.decision;
        println!(
            "approach {n}: {} | votes {} | {} frames, {} dropped{}",
            d.outcome,
            votes(&d.votes),
            d.frames,
            report.window.feed.dropped,
            match (&report.preshape, &report.expired) {
                (Some(c), _) => format!(
                    " | acknowledged {:.1} ms after the trigger ({} attempts)",
                    c.since_trigger_ms, c.attempts
                ),
                (None, Some(e)) => format!(
                    " | STALE: not acknowledged within {:.0} ms of the decision, not executed",
                    e.limit_ms
                ),
                (None, None) => String::new(),
            }
        );
        if let Some(e) = &report.link_error {
            eprintln!("approach {n}: link error: {e}");
        }
        if let (Some(hand), Some(_)) = (&report.hand, ApproachResult::of(report).exit_code(report))
        {
            eprintln!(
                "approach {n}: the hand last acknowledged {} ({}): {}{}",
                hand.command,
                hand.status,
                format!("{:?}", hand.state).to_lowercase(),
                hand.preshape
                    .map_or(String::new(), |p| format!(", {p} configuration"))
            );
        }
        if let Some(stop) = &report.stopped {
            let by = stop.signal.map_or("request".into(), |s| s.name());
            println!("approach {n}: STOPPED by {by} {}", stop.phase);
        }
        if let Some(path) = self.report {
            let line = ReportLine {
                approach: n,
                result: ApproachResult::of(report),
                model: &self.model,
                report,
            };
            append_json_line(path, &line)?;
        }
        Ok(())
    }
}

fn append_json_line(path: &Path, value: &impl serde::Serialize) -> Result<(), ReportError> {
    let failed = |doing, source| ReportError {
        doing,
        path: path.to_path_buf(),
        source,
    };
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(|e| failed("open", e))?;
    let line = serde_json::to_string(value).map_err(|e| failed("write", e.into()))?;
    writeln!(f, "{line}").map_err(|e| failed("write", e))
}
