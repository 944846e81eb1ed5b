//! The command line: each subcommand's flags, and the exit codes its
//! help lists.

use clap::Args;
use grasp_cli::{DecisionArgs, LensArgs};
use runtime::simhand::FaultSpec;
use std::path::PathBuf;

pub(crate) const RUN_EXIT_CODES: &str = "\
Exit codes:
  0  every approach ended as decided (pre-shape executed, or no command on a weak vote)
  1  error outside the approaches (arguments, config, checkpoint, source, report file)
  2  command-line usage error
  3  an approach was aborted (frame source or classifier failed, invalid model output,
     the closure trigger ended before it fired: the hand is opened)
  4  the hand could not be reached or did not acknowledge a command (the hand is
     opened if a command may have reached it; never closed unless it says it is
     in the decided pre-shape)
  5  a decision or closure was older than --max-decision-age-ms before the hand
     acknowledged it (the hand is opened if a copy may have reached it)
  128+N  stopped by signal N: 130 SIGINT (Ctrl-C), 143 SIGTERM, 129 SIGHUP; nothing
     is sent after it, and the hand is opened if a command may have reached it
With several approaches, the code of the first failed one (a stop counts where it
came). The last line on stderr says why.";

pub(crate) const REPLAY_EXIT_CODES: &str = "\
Exit codes (as `run`'s):
  0  a decision was taken (a pre-shape, or no command on a weak vote)
  1  error (arguments, config, checkpoint, source)
  2  command-line usage error
  3  aborted (frame source or classifier failed, invalid model output)";

#[derive(Args, Clone)]
pub(crate) struct PolicyArgs {
    /// Config file (TOML, sections [policy] and [link]); flags override it.
    #[arg(long)]
    pub(crate) config: Option<PathBuf>,
    /// A decision older than this (ms) is never executed: the pre-shape
    /// must be acknowledged within it of the vote (not of the frames'
    /// capture), the closure within it of its trigger (default 300).
    #[arg(long)]
    pub(crate) max_decision_age_ms: Option<u64>,
    #[command(flatten)]
    pub(crate) decision: DecisionArgs,
}

#[derive(Args, Clone)]
pub(crate) struct SourceArgs {
    /// Trained checkpoint (from grasp-train).
    #[arg(long)]
    pub(crate) checkpoint: PathBuf,
    /// A sequence folder (PNG frames, optionally sequence.json), or
    /// `camera[:DEVICE]` (needs the `camera` feature; default /dev/video0).
    #[arg(long)]
    pub(crate) source: String,
    /// Frame rate of a bare PNG folder (default: sequence.json, else 30).
    #[arg(long)]
    pub(crate) fps: Option<f64>,
    #[command(flatten)]
    pub(crate) lens: LensArgs,
}

#[derive(Args)]
pub(crate) struct RunArgs {
    #[command(flatten)]
    pub(crate) source: SourceArgs,
    #[command(flatten)]
    pub(crate) policy: PolicyArgs,
    /// Serial device of the hand (USB adapter, /dev/rfcomm0, pty link).
    #[arg(long)]
    pub(crate) port: PathBuf,
    /// Serial speed (both sides must agree; at least 1).
    #[arg(long, default_value_t = 115_200, value_parser = clap::value_parser!(u32).range(1..))]
    pub(crate) baud: u32,
    /// Starts an approach: `stdin` (Enter), `now`, or `timer:SECONDS`.
    #[arg(long, default_value = "stdin")]
    pub(crate) trigger: String,
    /// Closes the fingers after the pre-shape: `delay:SECONDS`, `stdin`, or
    /// `none`.
    #[arg(long, default_value = "delay:1.0")]
    pub(crate) closure: String,
    /// Number of approaches (default: 1 for a recording, unlimited for a
    /// camera).
    #[arg(long)]
    pub(crate) approaches: Option<usize>,
    /// Replay a recording as fast as possible instead of at its frame rate.
    #[arg(long)]
    pub(crate) as_fast: bool,
    /// Append one JSON report per approach to this file (with `approach`,
    /// its number, and `result`: commanded, no_command, aborted, expired,
    /// hand_failed, stopped).
    #[arg(long)]
    pub(crate) report: Option<PathBuf>,
}

#[derive(Args)]
pub(crate) struct ReplayArgs {
    #[command(flatten)]
    pub(crate) source: SourceArgs,
    #[command(flatten)]
    pub(crate) policy: PolicyArgs,
    /// Replay at the recording's frame rate, dropping frames the classifier
    /// cannot keep up with (default: every frame, as fast as possible).
    #[arg(long)]
    pub(crate) realtime: bool,
    /// Print the report as JSON instead of a table.
    #[arg(long)]
    pub(crate) json: bool,
}

#[derive(Args)]
pub(crate) struct SimArgs {
    /// Serve an existing serial device.
    #[arg(long, conflicts_with = "pty", required_unless_present = "pty")]
    pub(crate) port: Option<PathBuf>,
    /// Create a pseudo-terminal and link its host side at this path (with
    /// PATH.owner naming this process; both are removed when it stops).
    #[arg(long)]
    pub(crate) pty: Option<PathBuf>,
    /// Serial speed (both sides must agree; at least 1).
    #[arg(long, default_value_t = 115_200, value_parser = clap::value_parser!(u32).range(1..))]
    pub(crate) baud: u32,
    /// Inject link faults, e.g. `drop=0.1,corrupt=0.05,duplicate=0.1,
    /// delay=0.2:400,disconnect=0.05:1500,outage=1500:7500,after=1000,
    /// until=20000,on=preshape+close,seed=7` (probabilities per frame, times
    /// in ms; docs/hannes-protocol.md).
    #[arg(long, value_parser = parse_faults)]
    pub(crate) faults: Option<FaultSpec>,
}

pub(crate) fn parse_faults(s: &str) -> Result<FaultSpec, String> {
    s.parse()
}

#[derive(Args)]
pub(crate) struct BenchArgs {
    /// Checkpoint with an FC or trace head (from grasp-train). Latency does not
    /// depend on weight values: `grasp-train stand-in --out DIR` builds one
    /// without a dataset.
    #[arg(long)]
    pub(crate) checkpoint: PathBuf,
    /// Time the frames of a recording (a sequence folder, as for `replay`),
    /// decoded beforehand and repeated in order, instead of synthetic
    /// frames: the denoiser's time depends on what the frames show.
    #[arg(long, value_name = "DIR")]
    pub(crate) recording: Option<String>,
    /// The camera's lens: a recording's, when it has no sequence.json; the
    /// synthetic frames' (default: 42 degrees across).
    #[command(flatten)]
    pub(crate) lens: LensArgs,
    /// Timed inference frames (224x224 synthetic ones, or the recording's
    /// repeated).
    #[arg(long, default_value_t = 200)]
    pub(crate) frames: usize,
    /// Untimed warm-up frames.
    #[arg(long, default_value_t = 10)]
    pub(crate) warmup: usize,
    /// Time the inference frames at a camera's pace, one every 1/FPS s, as
    /// on the hand (30: the wrist camera); 0 runs them back to back, which
    /// keeps every core busy for the whole series.
    #[arg(long, default_value_t = 0.0, value_name = "FPS")]
    pub(crate) pace: f64,
    /// Link round trips to time (0: none).
    #[arg(long, default_value_t = 500)]
    pub(crate) sends: usize,
    /// Whole approaches (2 s window at 30 fps each) to time (0: none).
    #[arg(long, default_value_t = 5)]
    pub(crate) approaches: usize,
    /// Serial speed (both sides must agree; at least 1).
    #[arg(long, default_value_t = 115_200, value_parser = clap::value_parser!(u32).range(1..))]
    pub(crate) baud: u32,
    /// Input size of the synthetic frames.
    #[arg(long, default_value_t = 224, conflicts_with = "recording")]
    pub(crate) size: u32,
    /// What the inference line times: the whole frame (crop, denoise,
    /// resize, network, head), its preprocessing alone (crop, denoise,
    /// resize, normalisation), or the network alone (the backbone with its
    /// pooled blocks, no head) on prepared inputs.
    #[arg(long, value_enum, default_value_t = Stage::Frame)]
    pub(crate) stage: Stage,
    /// Also write each timed frame's time to FILE, in ms, one a line.
    #[arg(long, value_name = "FILE")]
    pub(crate) times: Option<PathBuf>,
}

/// The part of a frame `bench` times.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Stage {
    Frame,
    Prepare,
    Network,
}
