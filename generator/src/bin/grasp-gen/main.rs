#[cfg(feature = "lab")]
mod bench_plan;
#[cfg(feature = "lab")]
mod bench_queries;
mod dataset;
mod objects;
mod plan;
mod preview;
mod render;

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
    /// The object catalog: list, check, show, import-ycb.
    #[command(subcommand)]
    Objects(ObjectsCli),
    /// Render the configured sequences with headless Blender workers.
    Render(render::RenderArgs),
    /// Check a finished dataset, or merge shard outputs.
    #[command(subcommand)]
    Dataset(dataset::DatasetCommand),
    /// Write a contact sheet and an animated GIF of a few sequences.
    Preview(preview::PreviewArgs),
    /// Plan sequences (camera paths, labels, scene samples) without Blender.
    Plan(plan::PlanArgs),
    /// Time the planner and print the BENCHMARKS.md tables.
    #[cfg(feature = "lab")]
    #[command(hide = true)]
    BenchPlan(bench_plan::BenchArgs),
    /// A rendering worker process (started by `render`).
    #[command(hide = true)]
    Worker,
}

/// `objects`: the library's subcommands and, with the `lab` feature, the
/// developers' benchmark of the mesh queries.
#[derive(Subcommand)]
enum ObjectsCli {
    #[command(flatten)]
    Lib(objects::ObjectsCommand),
    /// Time the mesh queries (rays, inside tests, closest points) per
    /// object, for each ray backend, against trimesh's closest points.
    #[cfg(feature = "lab")]
    #[command(hide = true)]
    BenchQueries(bench_queries::BenchArgs),
}

fn main() -> std::process::ExitCode {
    grasp_main::main(|| {
        grasp_main::init_logging();
        let cli = Cli::parse();
        match cli.command {
            Command::Doctor => doctor(),
            Command::Objects(ObjectsCli::Lib(cmd)) => objects::run(&cmd),
            #[cfg(feature = "lab")]
            Command::Objects(ObjectsCli::BenchQueries(args)) => bench_queries::run_args(&args),
            Command::Render(args) => render::run_render(&args),
            Command::Dataset(cmd) => dataset::run(&cmd),
            Command::Preview(args) => preview::run(&args),
            Command::Worker => render::run_worker(),
            Command::Plan(args) => plan::run(&args),
            #[cfg(feature = "lab")]
            Command::BenchPlan(args) => bench_plan::run(&args),
        }
    })
}

fn doctor() -> Result<()> {
    let venv = generator::python::venv_dir();
    println!("Python venv: {}", venv.display());
    generator::python::init(&["numpy", "trimesh", "rtree", "bpy"])?;
    println!("numpy, trimesh, rtree and bpy import: ok");
    // bpy's leak detector would report Blender's own statics at exit.
    grasp_main::exit_now(0)
}
