use clap::Parser;

/// Drive the Hannes hand from a wrist camera.
#[derive(Parser)]
#[command(name = "hannes-run", version, about)]
struct Cli {}

fn main() -> anyhow::Result<()> {
    let _cli = Cli::parse();
    Ok(())
}
