//! `hannes-run`: the pre-shape classifier driving the Hannes hand. One
//! module per subcommand (`run`, `replay`, `simulate`, `bench`); `args`
//! holds the flags, `setup` what several subcommands open the same way,
//! `table` the printed rows.
mod args;
mod bench;
mod replay;
mod run;
mod setup;
mod simulate;
mod table;

use args::{BenchArgs, ReplayArgs, RunArgs, SimArgs, REPLAY_EXIT_CODES, RUN_EXIT_CODES};
use clap::{Parser, Subcommand};

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

fn main() -> std::process::ExitCode {
    grasp_main::main(|| {
        grasp_main::init_logging();
        dispatch(Cli::parse())
    })
}

fn dispatch(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Cmd::Run(a) => run::run(a),
        Cmd::Replay(a) => replay::replay(a),
        Cmd::SimulateHand(a) => simulate::simulate_hand(a),
        Cmd::Bench(a) => bench::command(a),
    }
}
