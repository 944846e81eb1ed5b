use anyhow::Result;
use clap::{Parser, Subcommand};

/// Synthetic reach-to-grasp sequences for hand pre-shape classification.
#[derive(Parser)]
#[command(name = "grasp-gen", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print where the Python environment is expected and whether it works.
    Doctor,
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    match cli.command {
        Command::Doctor => doctor(),
    }
}

fn doctor() -> Result<()> {
    let venv = generator::python::venv_dir();
    println!("Python venv: {}", venv.display());
    generator::python::init(&["numpy", "trimesh", "rtree", "bpy"])?;
    println!("numpy, trimesh, rtree and bpy import: ok");
    Ok(())
}
