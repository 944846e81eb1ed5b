//! The `dataset verify` and `dataset merge` subcommands.

use anyhow::{bail, Result};
use clap::Subcommand;
use generator::config::ConfigArgs;
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum DatasetCommand {
    /// Check a finished dataset: counts per pair and condition, missing,
    /// truncated or corrupt files, manifest, and (with --config) that every
    /// configured sequence is there, each record equals a fresh plan and was
    /// rendered with the config's render settings.
    Verify {
        dir: PathBuf,
        /// The config the dataset was made with (the files and --set
        /// values given to render); enables the re-plan check.
        #[command(flatten)]
        config: ConfigArgs,
        /// Also decode every image fully (by default each file's structure
        /// and checksums are checked: PNG chunk CRCs up to IEND, EXR chunks).
        #[arg(long)]
        decode: bool,
        /// With --config: the folder is the output of `render --shard K/N`;
        /// only that shard's sequences are expected.
        #[arg(long, default_value = "0/1")]
        shard: generator::dataset::shard::Shard,
    },
    /// Join shard outputs into OUT (copies, or hard links where possible).
    Merge { out: PathBuf, shards: Vec<PathBuf> },
    /// Frames and measured render seconds per frame, per camera.
    Stats {
        dir: PathBuf,
        /// Print JSON (for plots) instead of a table.
        #[arg(long)]
        json: bool,
    },
}

pub fn run(cmd: &DatasetCommand) -> Result<()> {
    match cmd {
        DatasetCommand::Verify {
            dir,
            config,
            decode,
            shard,
        } => {
            let report = match config.is_given() {
                true => {
                    let config = config.load()?;
                    let source = generator::plan::PlannerSource::new(&config)?;
                    generator::dataset::verify::verify_config(
                        dir,
                        &source,
                        &config.render,
                        *decode,
                        *shard,
                    )?
                }
                false => generator::dataset::verify::verify_shard(dir, None, *decode, *shard)?,
            };
            print!("{}", report.render_text());
            if !report.ok() {
                bail!("{}: {} problems", dir.display(), report.problems.len());
            }
            println!("ok");
            Ok(())
        }
        DatasetCommand::Stats { dir, json } => {
            let s = generator::dataset::stats::stats(dir)?;
            if *json {
                println!("{}", serde_json::to_string_pretty(&s)?);
            } else {
                print!("{}", s.render_text());
            }
            Ok(())
        }
        DatasetCommand::Merge { out, shards } => {
            if shards.is_empty() {
                bail!("dataset merge: give at least one shard folder");
            }
            let s = generator::dataset::merge::merge(out, shards)?;
            println!(
                "{}: {} sequences copied, {} already present",
                out.display(),
                s.copied,
                s.already_present
            );
            Ok(())
        }
    }
}
