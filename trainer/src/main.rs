use clap::Parser;

/// Train and evaluate pre-shape classifiers on generated or real sequences.
#[derive(Parser)]
#[command(name = "grasp-train", version, about)]
struct Cli {}

fn main() -> anyhow::Result<()> {
    let _cli = Cli::parse();
    Ok(())
}
