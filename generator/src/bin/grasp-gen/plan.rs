//! `grasp-gen plan`: write plans as JSON lines and/or draw them.

use anyhow::{bail, Context, Result};
use generator::catalog::Catalog;
use generator::config::{ConfigArgs, GeneratorConfig};
use generator::plan::{sequence_keys, Planner};
use grasp_schema::SequencePlan;
use grasp_support::atomic::AtomicFile;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `grasp-gen plan`.
#[derive(Debug, clap::Args)]
pub struct PlanArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
    /// Object catalog folder; the built-in catalog when omitted.
    #[arg(long)]
    pub catalog: Option<PathBuf>,
    /// Write every planned sequence here, one JSON object per line.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Draw top and side views of planned paths into this PNG.
    #[arg(long)]
    pub show: Option<PathBuf>,
    /// With --show: paths drawn per (object, part) pair and condition.
    #[arg(long, default_value_t = 6)]
    pub show_per_pair: u32,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

pub fn load_inputs(
    config: &ConfigArgs,
    catalog: Option<&Path>,
) -> Result<(GeneratorConfig, Catalog)> {
    let config = config.load()?;
    config
        .plan
        .validate()
        .context("invalid [plan] section of the config")?;
    let catalog = match catalog {
        Some(dir) => Catalog::load_dir(dir)
            .with_context(|| format!("loading the catalog {}", dir.display()))?,
        None => Catalog::builtin().context("loading the built-in catalog")?,
    };
    generator::plan::check::check(&config, &catalog)?;
    Ok((config, catalog))
}

pub fn run(args: &PlanArgs) -> Result<()> {
    if args.out.is_none() && args.show.is_none() {
        bail!("nothing to do: give --out FILE.jsonl and/or --show FILE.png");
    }
    let (config, catalog) = load_inputs(&args.config, args.catalog.as_deref())?;
    let mut keys = sequence_keys(&config, &catalog);
    if keys.is_empty() {
        bail!("the config selects no sequences (check dataset.objects, dataset.parts and dataset.conditions)");
    }
    if args.out.is_none() {
        keys.retain(|k| k.index < args.show_per_pair);
    }
    let planner = Planner::new(&config, &catalog)?;
    let started = Instant::now();
    // Plans are written as they are made and only the drawn ones are kept:
    // memory does not grow with the number of sequences.
    let mut sink = args.out.as_deref().map(AtomicFile::create).transpose()?;
    let mut shown = Vec::new();
    let bar = progress_bar(keys.len(), args.quiet);
    for key in &keys {
        let plan = planner.plan(key)?;
        bar.inc(1);
        if let Some(w) = sink.as_mut() {
            push_line(w, &plan)?;
        }
        if args.show.is_some() && plan.key.index < args.show_per_pair {
            shown.push(plan);
        }
    }
    bar.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    eprintln!(
        "planned {} sequences in {secs:.2} s ({:.2} ms per sequence)",
        keys.len(),
        1e3 * secs / keys.len() as f64
    );
    if let (Some(w), Some(out)) = (sink, &args.out) {
        w.commit()?;
        eprintln!("wrote {}", out.display());
    }
    if let Some(png) = &args.show {
        let shown: Vec<&SequencePlan> = shown.iter().collect();
        generator::plan::plot_paths::draw_paths(&shown, &planner, png)?;
        eprintln!("drew {} paths into {}", shown.len(), png.display());
    }
    Ok(())
}

/// Appends `plan` as one JSON line.
fn push_line(out: &mut AtomicFile, plan: &SequencePlan) -> Result<()> {
    serde_json::to_writer(&mut *out, plan)
        .map_err(anyhow::Error::from)
        .and_then(|_| Ok(out.write_all(b"\n")?))
        .with_context(|| format!("writing {}", out.path().display()))
}

fn progress_bar(len: usize, quiet: bool) -> indicatif::ProgressBar {
    let bar = if quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(len as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "planning {bar:40} {pos}/{len} [{elapsed} < {eta}] {msg}",
        )
        .expect("valid template"),
    );
    bar
}

/// Plans every key in order, with a progress bar (`bench-plan`'s).
#[cfg(feature = "lab")]
pub fn plan_all(
    planner: &Planner,
    keys: &[grasp_schema::SequenceKey],
    quiet: bool,
) -> Result<Vec<SequencePlan>> {
    let bar = progress_bar(keys.len(), quiet);
    let plans = keys
        .iter()
        .map(|k| {
            bar.inc(1);
            planner.plan(k)
        })
        .collect::<Result<Vec<_>, _>>()?;
    bar.finish_and_clear();
    Ok(plans)
}
