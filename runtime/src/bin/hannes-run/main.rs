//! `hannes-run`: the pre-shape classifier driving the Hannes hand.
mod bench;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use grasp_cli::LensArgs;
use grasp_model::checkpoint::Classifier;
use grasp_model::input::{Crop, Lens};
use grasp_schema::taxonomy::{Class, Preshape};
use grasp_support::cli::Failure;
use runtime::approach::{classify_window, ApproachReport, FramePrediction};
use runtime::config::RuntimeConfig;
use runtime::feed::FeedMode;
use runtime::link::{Hand, HandLink};
use runtime::policy::OnInvalid;
use runtime::session::{ApproachResult, Session, SessionObserver};
use runtime::simhand::{DevicePort, FaultSpec, HandEvent, Plug, PtyPlug, RunningHand};
use runtime::source::{FrameSource, Pacing, SequenceFolder};
use runtime::transport::SerialConnector;
use runtime::trigger::{parse_trigger, Trigger};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

const RUN_EXIT_CODES: &str = "\
Exit codes:
  0  every approach ended as decided (pre-shape executed, or no command on a weak vote)
  1  error outside the approaches (arguments, config, checkpoint, source, report file)
  2  command-line usage error
  3  an approach was aborted (frame source or classifier failed, invalid model output)
  4  the hand could not be reached or did not acknowledge a command
  5  a decision was older than --max-decision-age-ms before the hand acknowledged it
     (not executed, no closure; the hand is opened if a copy may have reached it)
  128+N  stopped by signal N: 130 SIGINT (Ctrl-C), 143 SIGTERM, 129 SIGHUP; nothing
     is sent after it, and the hand is opened if a command may have reached it
With several approaches, the code of the first failed one (a stop counts where it
came). The last line on stderr says why.";

const REPLAY_EXIT_CODES: &str = "\
Exit codes (as `run`'s):
  0  a decision was taken (a pre-shape, or no command on a weak vote)
  1  error (arguments, config, checkpoint, source)
  2  command-line usage error
  3  aborted (frame source or classifier failed, invalid model output)";

/// Drive the Hannes hand from a wrist camera: classify the frames of each
/// approach, pick the pre-shape by majority vote and send it over the
/// serial link (protocol: docs/hannes-protocol.md).
#[derive(Parser)]
#[command(name = "hannes-run", version, about, after_help = RUN_EXIT_CODES)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// The demo: trigger, approach window, pre-shape, closure; repeated.
    #[command(after_help = RUN_EXIT_CODES)]
    Run(RunArgs),
    /// Classify a recorded sequence; print per-frame predictions and the
    /// decision (no hand needed).
    #[command(after_help = REPLAY_EXIT_CODES)]
    Replay(ReplayArgs),
    /// The hand side of the protocol, simulated; prints one JSON line per
    /// event.
    SimulateHand(SimArgs),
    /// Inference, link and trigger-to-command latency.
    Bench(BenchArgs),
}

#[derive(Args, Clone)]
struct PolicyArgs {
    /// Config file (TOML, sections [policy] and [link]); flags override it.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Approach window in seconds.
    #[arg(long)]
    window: Option<f64>,
    /// A decision older than this (ms) is never executed: the pre-shape
    /// must be acknowledged within it of the vote (not of the frames'
    /// capture), the closure within it of its trigger (default 300).
    #[arg(long)]
    max_decision_age_ms: Option<u64>,
    /// Decide early once the leading pre-shape is this many votes ahead.
    #[arg(long)]
    early_margin: Option<u32>,
    /// Pre-shape sent on low confidence (power, lateral, pinch, pinch3), or
    /// `none` to send nothing.
    #[arg(long)]
    fallback: Option<String>,
    /// Minimum mean probability of the winning class.
    #[arg(long)]
    min_confidence: Option<f64>,
    /// What an invalid model output (NaN, Inf) does.
    #[arg(long, value_enum)]
    on_invalid: Option<OnInvalid>,
}

#[derive(Args, Clone)]
struct SourceArgs {
    /// Trained checkpoint (from grasp-train).
    #[arg(long)]
    checkpoint: PathBuf,
    /// A sequence folder (PNG frames, optionally sequence.json), or
    /// `camera[:DEVICE]` (needs the `camera` feature; default /dev/video0).
    #[arg(long)]
    source: String,
    /// Frame rate of a bare PNG folder (default: sequence.json, else 30).
    #[arg(long)]
    fps: Option<f64>,
    #[command(flatten)]
    lens: LensArgs,
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    source: SourceArgs,
    #[command(flatten)]
    policy: PolicyArgs,
    /// Serial device of the hand (USB adapter, /dev/rfcomm0, pty link).
    #[arg(long)]
    port: PathBuf,
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// Starts an approach: `stdin` (Enter), `now`, or `timer:SECONDS`.
    #[arg(long, default_value = "stdin")]
    trigger: String,
    /// Closes the fingers after the pre-shape: `delay:SECONDS`, `stdin`, or
    /// `none`.
    #[arg(long, default_value = "delay:1.0")]
    closure: String,
    /// Number of approaches (default: 1 for a recording, unlimited for a
    /// camera).
    #[arg(long)]
    approaches: Option<usize>,
    /// Replay a recording as fast as possible instead of at its frame rate.
    #[arg(long)]
    as_fast: bool,
    /// Append one JSON report per approach to this file (with `approach`,
    /// its number, and `result`: commanded, no_command, aborted, expired,
    /// hand_failed, stopped).
    #[arg(long)]
    report: Option<PathBuf>,
}

#[derive(Args)]
struct ReplayArgs {
    #[command(flatten)]
    source: SourceArgs,
    #[command(flatten)]
    policy: PolicyArgs,
    /// Replay at the recording's frame rate, dropping frames the classifier
    /// cannot keep up with (default: every frame, as fast as possible).
    #[arg(long)]
    realtime: bool,
    /// Print the report as JSON instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct SimArgs {
    /// Serve an existing serial device.
    #[arg(long, conflicts_with = "pty", required_unless_present = "pty")]
    port: Option<PathBuf>,
    /// Create a pseudo-terminal and link its host side at this path (with
    /// PATH.owner naming this process; both are removed when it stops).
    #[arg(long)]
    pty: Option<PathBuf>,
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// Inject link faults, e.g. `drop=0.1,corrupt=0.05,duplicate=0.1,
    /// delay=0.2:400,disconnect=0.05:1500,outage=1500:7500,after=1000,
    /// until=20000,on=preshape+close,seed=7` (probabilities per frame, times
    /// in ms; docs/hannes-protocol.md).
    #[arg(long, value_parser = parse_faults)]
    faults: Option<FaultSpec>,
}

fn parse_faults(s: &str) -> Result<FaultSpec, String> {
    s.parse()
}

#[derive(Args)]
struct BenchArgs {
    /// Checkpoint with an FC head (from grasp-train). Latency does not
    /// depend on weight values: `grasp-train stand-in --out DIR` builds one
    /// without a dataset.
    #[arg(long)]
    checkpoint: PathBuf,
    /// Timed inference frames (224x224).
    #[arg(long, default_value_t = 200)]
    frames: usize,
    /// Untimed warm-up frames.
    #[arg(long, default_value_t = 10)]
    warmup: usize,
    /// Link round trips to time.
    #[arg(long, default_value_t = 500)]
    sends: usize,
    /// Whole approaches (2 s window at 30 fps each) to time.
    #[arg(long, default_value_t = 5)]
    approaches: usize,
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// Input size of the timed frames.
    #[arg(long, default_value_t = 224)]
    size: u32,
}

fn main() -> std::process::ExitCode {
    grasp_support::cli::main(|| {
        grasp_support::cli::init_logging();
        dispatch(Cli::parse())
    })
}

fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Cmd::Run(a) => run(a),
        Cmd::Replay(a) => replay(a),
        Cmd::SimulateHand(a) => simulate_hand(a),
        Cmd::Bench(a) => bench(a),
    }
}

fn stop_flag() -> Result<&'static std::sync::atomic::AtomicBool> {
    runtime::signals::stop_flag().context("cannot install the signal handlers")
}

fn config(policy_args: &PolicyArgs) -> Result<RuntimeConfig> {
    let mut cfg = match &policy_args.config {
        Some(path) => RuntimeConfig::load(path)?,
        None => RuntimeConfig::default(),
    };
    let policy = &mut cfg.policy;
    if let Some(w) = policy_args.window {
        policy.window_s = w;
    }
    if policy_args.early_margin.is_some() {
        policy.early_margin = policy_args.early_margin;
    }
    if let Some(f) = &policy_args.fallback {
        policy.fallback = match f.as_str() {
            "none" => None,
            name => Some(name.parse::<Preshape>().context("--fallback")?),
        };
    }
    if let Some(c) = policy_args.min_confidence {
        policy.min_confidence = c;
    }
    if let Some(o) = policy_args.on_invalid {
        policy.on_invalid = o;
    }
    if let Some(ms) = policy_args.max_decision_age_ms {
        policy.max_decision_age_ms = ms;
    }
    cfg.validate()?;
    Ok(cfg)
}

/// Opens the frame source; returns it with whether it is live. The
/// classifier learns the camera's lens (the flags', else the recording's),
/// and a recording must hold every pixel its crop looks at.
fn open_source(
    source_args: &SourceArgs,
    pacing: Pacing,
    classifier: &mut Classifier,
) -> Result<(Box<dyn FrameSource>, bool)> {
    if let Some(rest) = source_args.source.strip_prefix("camera") {
        set_lens(classifier, source_args.lens.lens()?, &source_args.source)?;
        let device = rest.strip_prefix(':').unwrap_or("/dev/video0");
        return Ok((open_camera(Path::new(device))?, true));
    }
    let folder = open_recording(source_args, pacing, classifier)?;
    Ok((Box::new(folder), false))
}

/// Opens a recording for `classifier`: sets the lens its crop needs and
/// checks, at the frames' own size, that the recording holds every pixel
/// the crop sees.
fn open_recording(
    source_args: &SourceArgs,
    pacing: Pacing,
    classifier: &mut Classifier,
) -> Result<SequenceFolder> {
    let dir = Path::new(&source_args.source);
    let folder = SequenceFolder::open(dir, source_args.fps, pacing)?;
    let lens = match source_args.lens.lens()? {
        Some(lens) => Some(lens),
        None => folder.info().lens()?,
    };
    set_lens(classifier, lens, &source_args.source)?;
    let (width, height) = folder.frame_size()?;
    let crop = classifier.crop_fraction(width, height).with_context(|| {
        format!(
            "cannot crop the {width}x{height} frames of {}",
            dir.display()
        )
    })?;
    folder.info().check_crop(crop, dir)?;
    Ok(folder)
}

/// Gives the classifier the camera's lens; one that crops a fixed angle
/// refuses to start without it.
fn set_lens(classifier: &mut Classifier, lens: Option<Lens>, source: &str) -> Result<()> {
    match (lens, classifier.input().crop) {
        (Some(lens), _) => classifier.set_lens(lens),
        (None, Crop::AngleDeg(angle)) => anyhow::bail!(
            "the checkpoint crops a fixed angle of {angle} degrees, so it needs the camera's \
             lens: {source} does not record one (no sequence.json with plan.intrinsics); give \
             --focal-px with --lens-size, --hfov-deg or --lens-file"
        ),
        (None, _) => {}
    }
    Ok(())
}

#[cfg(feature = "camera")]
fn open_camera(device: &Path) -> Result<Box<dyn FrameSource>> {
    Ok(Box::new(runtime::camera::Camera::open(
        device, 640, 480, 30,
    )?))
}

#[cfg(not(feature = "camera"))]
fn open_camera(device: &Path) -> Result<Box<dyn FrameSource>> {
    anyhow::bail!(
        "cannot open {}: hannes-run was built without the `camera` feature \
         (rebuild with `cargo build --release -p runtime --features camera`)",
        device.display()
    )
}

fn run(args: RunArgs) -> Result<()> {
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
    let mut stdin = None;
    let mut trigger = parse_trigger(&args.trigger, &mut stdin)?;
    let mut closure = match args.closure.as_str() {
        "none" => None,
        spec => Some(parse_trigger(spec, &mut stdin)?),
    };
    let link = HandLink::new(
        Box::new(SerialConnector::new(&args.port, args.baud)),
        cfg.link.clone(),
    );
    let hand = match Hand::start(link) {
        Ok(hand) => hand,
        Err(e) => {
            let code = runtime::session::exit_code_before_approaches(&e);
            return Err(e.context(Failure::new(code, "cannot start the link to the hand")));
        }
    };
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
    let closure = closure.as_mut().map(|c| c.as_mut() as &mut dyn Trigger);
    let (_, summary) = session.run(source, approaches, trigger.as_mut(), closure, &mut printer)?;
    let stats = hand.stats();
    eprintln!(
        "link: {} transmissions, {} retransmissions, {} heartbeats, {} reconnects, {} CRC errors",
        stats.transmissions,
        stats.retransmissions,
        stats.heartbeats,
        stats.reconnects,
        stats.rx_crc_errors
    );
    eprintln!("{}", summary.describe());
    match summary.failure_message() {
        Some(reason) => Err(Failure::new(summary.exit_code(), reason).into()),
        None => Ok(()),
    }
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

    fn approach(&mut self, n: usize, report: &ApproachReport) -> Result<()> {
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

fn votes(votes: &[u32; Class::COUNT]) -> String {
    Class::ALL
        .iter()
        .map(|c| format!("{c} {}", votes[c.index()]))
        .collect::<Vec<_>>()
        .join(", ")
}

fn append_json_line(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .with_context(|| format!("cannot open report {}", path.display()))?;
    writeln!(f, "{}", serde_json::to_string(value)?)
        .with_context(|| format!("cannot write report {}", path.display()))
}

fn replay(args: ReplayArgs) -> Result<()> {
    let cfg = config(&args.policy)?;
    let mut classifier = runtime::model::load(&args.source.checkpoint)?;
    let pacing = if args.realtime {
        Pacing::RealTime
    } else {
        Pacing::AsFastAsPossible
    };
    let folder = open_recording(&args.source, pacing, &mut classifier)?;
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
        #[derive(serde::Serialize)]
        struct ReplayJson<'a, W: serde::Serialize> {
            model: runtime::model::ModelRecord,
            #[serde(flatten)]
            window: &'a W,
        }
        let out = ReplayJson {
            model: runtime::model::ModelRecord::of(
                &classifier,
                &args.source.checkpoint,
                args.source.lens.given(),
            ),
            window: &window,
        };
        println!("{}", serde_json::to_string_pretty(&out)?);
        return replay_result(&window.decision);
    }
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
    replay_result(d)
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

fn header() -> String {
    let classes: Vec<String> = Class::ALL.iter().map(|c| format!("{c:>8}")).collect();
    format!(
        "frame   time_s  {}  predicted  label     ms",
        classes.join("")
    )
}

fn row(prediction: &FramePrediction, truth: Option<Class>) -> String {
    let probs: Vec<String> = prediction
        .probabilities
        .iter()
        .map(|v| format!("{v:>8.3}"))
        .collect();
    let class = prediction
        .class
        .map_or("INVALID".to_string(), |c| c.to_string());
    let truth = truth.map_or("-".to_string(), |c| c.to_string());
    format!(
        "{:>5} {:>8.3}  {}  {:<9}  {:<8} {:>5.1}",
        prediction.index,
        prediction.time_s,
        probs.join(""),
        class,
        truth,
        prediction.inference_ms
    )
}

fn simulate_hand(args: SimArgs) -> Result<()> {
    let stop = stop_flag()?;
    let started = Instant::now();
    let sink = move |e: &HandEvent| print_event(started, e);
    let faults = args.faults.unwrap_or_default();
    if faults.is_active() {
        eprintln!("injecting link faults: {faults}");
    }
    let (plug, ready): (Box<dyn Plug>, String) = match (&args.pty, &args.port) {
        (Some(link), _) => (
            Box::new(PtyPlug::new(link)?),
            format!(
                "simulated hand listening; connect the host to {}",
                link.display()
            ),
        ),
        (None, Some(port)) => (
            Box::new(DevicePort {
                path: port.clone(),
                baud: args.baud,
            }),
            format!("simulated hand serving {}", port.display()),
        ),
        (None, None) => unreachable!("clap requires --port or --pty"),
    };
    let hand = RunningHand::start(plug, faults, sink)?;
    eprintln!("{ready}");
    while !stop.load(Ordering::Relaxed) && !hand.is_finished() {
        std::thread::sleep(Duration::from_millis(50));
    }
    // Stopping ends the serving thread, which unplugs: the link and its
    // owner record are removed.
    hand.stop().context("simulated hand failed")
}

fn print_event(started: Instant, e: &HandEvent) {
    let mut v = serde_json::to_value(e).unwrap_or_default();
    if let Some(obj) = v.as_object_mut() {
        obj.insert(
            "t_ms".into(),
            serde_json::json!(started.elapsed().as_millis() as u64),
        );
    }
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{v}");
    let _ = out.flush();
}

fn bench(args: BenchArgs) -> Result<()> {
    let mut classifier = runtime::model::load(&args.checkpoint)?;
    // A fixed-angle crop is timed through the default lens (42 degrees
    // across the square frame, the generator's d435 preset).
    set_lens(
        &mut classifier,
        Some(Lens::horizontal_fov(42.0)?),
        "the benchmark",
    )?;
    let frames = bench::synthetic_frames(args.frames.max(1), args.size);
    let inference = bench::inference(&mut classifier, &frames, args.warmup)?;
    println!(
        "inference {}x{} ({} frames): p50 {:.2} ms, p99 {:.2} ms, mean {:.2} ms, max {:.2} ms",
        args.size,
        args.size,
        inference.n,
        inference.p50_ms,
        inference.p99_ms,
        inference.mean_ms,
        inference.max_ms
    );
    let link = bench::link_round_trip(args.sends.max(1), args.baud)?;
    println!(
        "link PRESHAPE->ACK over a pty at {} baud ({} sends): p50 {:.3} ms, p99 {:.3} ms",
        link.baud, link.round_trip.n, link.round_trip.p50_ms, link.round_trip.p99_ms
    );
    let window = bench::synthetic_frames(60, args.size);
    let ap = bench::approaches(
        &mut classifier,
        window,
        30.0,
        args.approaches.max(1),
        args.baud,
    )?;
    println!(
        "approach (window {} s at {} fps, {} runs): trigger->ACK p50 {:.1} ms, p99 {:.1} ms; \
         after the window p50 {:.1} ms, p99 {:.1} ms; {} frames classified, {} dropped",
        ap.window_s,
        ap.fps,
        ap.trigger_to_command.n,
        ap.trigger_to_command.p50_ms,
        ap.trigger_to_command.p99_ms,
        ap.after_window.p50_ms,
        ap.after_window.p99_ms,
        ap.frames_classified,
        ap.frames_dropped
    );
    Ok(())
}
