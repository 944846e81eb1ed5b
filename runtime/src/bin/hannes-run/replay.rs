//! `hannes-run replay`: one recording classified, its frames and decision
//! printed as a table or as JSON (no hand needed).

use crate::args::ReplayArgs;
use crate::setup::{config, open_recording};
use crate::table::{header, row, votes};
use anyhow::Result;
use grasp_main::Failure;
use grasp_model::checkpoint::Classifier;
use runtime::approach::{classify_window, FramePrediction, WindowReport};
use runtime::feed::FeedMode;
use runtime::model::ModelRecord;
use runtime::source::{Pacing, SequenceInfo};
use std::time::Instant;

pub(crate) fn replay(args: ReplayArgs) -> Result<()> {
    let cfg = config(&args.policy)?;
    let mut classifier = runtime::model::load(&args.source.checkpoint)?;
    let pacing = if args.realtime {
        Pacing::RealTime
    } else {
        Pacing::AsFastAsPossible
    };
    let source = &args.source;
    let folder = open_recording(
        &source.source,
        source.fps,
        &source.lens,
        pacing,
        &mut classifier,
    )?;
    let info = folder.info().clone();
    let mode = if args.realtime {
        FeedMode::Latest
    } else {
        FeedMode::Lockstep
    };
    let json = args.json;
    if !json {
        println!("{}", header());
    }
    let mut print = |p: &FramePrediction| {
        if !json {
            let truth = info.labels.get(p.index as usize).copied();
            println!("{}", row(p, truth));
        }
    };
    let (_, window) = classify_window(
        Box::new(folder),
        mode,
        &mut classifier,
        &cfg.policy,
        Instant::now(),
        &mut print,
    )?;
    if json {
        print_json(&window, &classifier, &args)?;
    } else {
        print_summary(&window, &info);
    }
    replay_result(&window.decision)
}

/// The report of `--json`: the window with the model it was classified by.
#[derive(serde::Serialize)]
struct ReplayJson<'a> {
    model: ModelRecord,
    #[serde(flatten)]
    window: &'a WindowReport,
}

fn print_json(window: &WindowReport, classifier: &Classifier, args: &ReplayArgs) -> Result<()> {
    let out = ReplayJson {
        model: ModelRecord::of(
            classifier,
            &args.source.checkpoint,
            args.source.lens.given(),
        ),
        window,
    };
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// The decision under the table, checked against the recording's label.
fn print_summary(window: &WindowReport, info: &SequenceInfo) {
    let d = &window.decision;
    println!("decision: {}", d.outcome);
    println!("votes: {}", votes(&d.votes));
    if let Some(truth) = info.preshape {
        let verdict = match d.outcome.preshape() {
            Some(p) if p == truth => "correct",
            _ => "WRONG",
        };
        println!("label: {truth} ({verdict})");
    }
    println!(
        "frames: {} classified, {} dropped, {} invalid",
        window.feed.delivered, window.feed.dropped, d.invalid_frames
    );
}

/// Replay fails like `run` on the same recording: an aborted window exits
/// with [`runtime::session::EXIT_ABORTED`].
fn replay_result(decision: &runtime::policy::Decision) -> Result<()> {
    match &decision.outcome {
        runtime::policy::Outcome::Aborted { .. } => {
            Err(Failure::new(runtime::session::EXIT_ABORTED, decision.outcome.to_string()).into())
        }
        _ => Ok(()),
    }
}
