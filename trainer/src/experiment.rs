//! A whole experiment: split the data, train one model per seed, evaluate
//! each on the test split and write the aggregated report (mean ± std over
//! seeds).

use crate::config::TrainConfig;
use crate::data::{split, BadData, Dataset};
use crate::error::{DataError, EvalError, Result, TrainError};
use crate::eval::metrics::Scoring;
use crate::eval::metrics::VideoOutcome;
use crate::eval::report::RunReport;
use crate::eval::{compute_metrics, write_report, Report};
use crate::features::FeatureCache;
use crate::plan::{CachePlan, RunPlan};
use crate::train::{self, TrainOutcome};
use candle_core::Device;
use grasp_model::checkpoint::{CheckpointMeta, Classifier};
use std::path::{Path, PathBuf};

/// Width of the accuracy-against-time bins, in seconds.
pub const TIME_BIN_S: f64 = 0.1;

pub struct ExperimentOutcome {
    pub runs: Vec<TrainOutcome>,
    pub report: Option<Report>,
}

/// The folder seed `k` of a run trains into.
pub fn seed_dir(cfg: &TrainConfig, k: usize) -> PathBuf {
    seed_folder(&cfg.out, cfg.seed, k)
}

fn seed_folder(out: &Path, first_seed: u64, k: usize) -> PathBuf {
    out.join(format!("seed-{}", first_seed + k as u64))
}

/// Refuses a run whose seed folders already hold a checkpoint, so that a
/// finished run is never trained over by mistake (`--overwrite` skips it).
pub fn check_no_checkpoint(cfg: &TrainConfig, seeds: usize) -> Result<(), TrainError> {
    for k in 0..seeds.max(1) {
        let dir = seed_dir(cfg, k);
        if dir.join("best.json").exists() {
            return Err(TrainError::CheckpointExists { dir });
        }
    }
    Ok(())
}

/// Trains `seeds` models (seeds `cfg.seed`, `cfg.seed + 1`, ...) into
/// `cfg.out/seed-N/`, then evaluates them on the test split into
/// `cfg.out/report/` when there is one. The config is resolved first
/// ([`RunPlan`]); each step then reads its own section of the plan.
pub fn run(cfg: &TrainConfig, seeds: usize) -> Result<ExperimentOutcome> {
    let plan = RunPlan::resolve(cfg)?;
    let bad = BadData::new(plan.on_bad_data);
    let splits = train::load_splits(&plan.data, &bad)?;
    crate::data::coverage::check_training_classes(&splits.train, plan.data.allow_missing_classes)?;
    record_run(&plan, &splits)?;
    tracing::info!(
        "{} train / {} val / {} test sequences ({} mode, {} head)",
        splits.train.sequences.len(),
        splits.val.sequences.len(),
        splits.test.sequences.len(),
        cfg.mode.name(),
        cfg.head.name()
    );
    let RunPlan {
        out,
        first_seed,
        cache,
        features,
        fit,
        ..
    } = plan;
    let prep = train::prepare(features, &cache, &splits, &bad, &Device::Cpu)?;
    let mut runs = Vec::new();
    for k in 0..seeds.max(1) {
        let seed = first_seed + k as u64;
        let dir = seed_folder(&out, first_seed, k);
        tracing::info!("training seed {seed} into {}", dir.display());
        runs.push(train::train(&fit, &prep, seed, &dir)?);
    }
    drop(prep);
    let report = match splits.test.sequences.is_empty() {
        true => None,
        false => Some(evaluate_run(&runs, &splits.test, &cache, &bad, &out)?),
    };
    write_problems(&bad, &out)?;
    Ok(ExperimentOutcome { runs, report })
}

/// The run's folder with its split and its config as run.
fn record_run(plan: &RunPlan, splits: &train::Splits) -> Result<()> {
    std::fs::create_dir_all(&plan.out).map_err(|source| TrainError::Create {
        path: plan.out.clone(),
        source,
    })?;
    splits.split.save(&plan.out.join("split.json"))?;
    grasp_support::atomic::write_atomic(
        &plan.out.join("config.toml"),
        toml::to_string(&plan.recorded)?.as_bytes(),
    )?;
    Ok(())
}

/// The run's checkpoints scored on its test split, into `out/report/`.
fn evaluate_run(
    runs: &[TrainOutcome],
    test: &Dataset,
    cache: &CachePlan,
    bad: &BadData,
    out: &Path,
) -> Result<Report> {
    let ckpts: Vec<PathBuf> = runs.iter().map(|r| r.checkpoint.clone()).collect();
    let mut r = evaluate(
        &ckpts,
        test,
        &cache.dir,
        cache.batch,
        bad,
        &Scoring::default(),
    )?;
    r.bad_data = bad_data_note(bad, Path::new("../problems.json"));
    write_report(&r, &out.join("report"))?;
    Ok(r)
}

/// A report's note of the skipped problems, if any.
pub fn bad_data_note(bad: &BadData, listed_in: &Path) -> Option<crate::eval::report::BadDataNote> {
    let n = bad.problems().len();
    (n > 0).then(|| crate::eval::report::BadDataNote {
        skipped: n,
        listed_in: listed_in.to_path_buf(),
    })
}

/// Evaluates checkpoints on `data` and aggregates them into one report,
/// scoring only the frames in `window`. The checkpoints must share their
/// mode, backbone and training-set cap.
pub fn evaluate(
    checkpoints: &[PathBuf],
    data: &Dataset,
    cache_dir: &Path,
    batch: usize,
    bad: &BadData,
    scoring: &Scoring,
) -> Result<Report, EvalError> {
    let window = &scoring.window;
    window.validate()?;
    let mut outside = 0;
    let dev = Device::Cpu;
    let cache = FeatureCache::new(cache_dir, batch);
    let mut runs = Vec::new();
    let mut frames = crate::eval::html::FrameRecord::new(data);
    let (mut mode, mut backbone, mut cap) = (None, None, None);
    let (mut head, mut train_sequences) = (String::new(), None);
    let mut head_kind = None;
    let mut seen: Vec<(PathBuf, PathBuf)> = Vec::new();
    for ckpt in checkpoints {
        // One checkpoint given twice would count as two seeds.
        let real = ckpt.canonicalize().unwrap_or_else(|_| ckpt.clone());
        if let Some((first, _)) = seen.iter().find(|(_, r)| *r == real) {
            return Err(EvalError::DuplicateCheckpoint {
                first: first.clone(),
                checkpoint: ckpt.clone(),
            });
        }
        seen.push((ckpt.clone(), real));
        let clf = Classifier::load(ckpt, &dev)?;
        let m = &clf.meta;
        // The report scores class indices as the runtime's classes.
        if clf.classes() != grasp_schema::taxonomy::Class::ALL {
            return Err(EvalError::Classes {
                checkpoint: ckpt.clone(),
                classes: clf.classes().iter().map(|c| c.to_string()).collect(),
            });
        }
        same(
            "heads",
            &mut head_kind,
            m.head.kind.name().to_string(),
            ckpt,
        )?;
        same("modes", &mut mode, m.mode.name().to_string(), ckpt)?;
        same("backbones", &mut backbone, m.backbone.describe(), ckpt)?;
        same("sequences_per_pair", &mut cap, m.sequences_per_pair(), ckpt)?;
        head = m.head.kind.name().to_string();
        train_sequences = train_sequences.or(m.train_sequences);
        let all = crate::eval::predict::predict_dataset(&clf, data, &cache, bad)?;
        check_outputs(ckpt, &all)?;
        let preds: Vec<_> = all.iter().filter_map(|v| window.apply(v)).collect();
        outside = all.len() - preds.len();
        if preds.is_empty() {
            let window = window.describe();
            return Err(EvalError::EmptyWindow { window });
        }
        frames.add_run(&preds);
        runs.push(RunReport {
            checkpoint: ckpt.clone(),
            seed: m.seed,
            metrics: compute_metrics(&preds, TIME_BIN_S, &scoring.policy),
            videos: preds
                .iter()
                .map(|v| VideoOutcome::of(v, &scoring.policy))
                .collect(),
        });
    }
    let mut report = Report::new(&mode.unwrap_or_default(), &head, &data.root, runs);
    report.backbone = backbone.unwrap_or_default();
    report.sequences_per_pair = cap.flatten();
    report.train_sequences = train_sequences;
    report.window = *window;
    report.policy = Some(scoring.policy.clone());
    report.videos_outside_window = outside;
    report.frames = Some(std::sync::Arc::new(frames));
    Ok(report)
}

/// Every output a probability distribution, as the runtime requires of
/// each frame ([`grasp_policy::Probabilities::new`]): a NaN or infinite
/// output is a broken model, not a prediction to score.
fn check_outputs(
    ckpt: &Path,
    videos: &[crate::eval::metrics::VideoPrediction],
) -> Result<(), EvalError> {
    for v in videos {
        for (k, p) in v.probs.iter().enumerate() {
            if let Err(e) = grasp_policy::Probabilities::new(*p) {
                return Err(EvalError::InvalidOutput {
                    checkpoint: ckpt.to_path_buf(),
                    video: v.id.clone(),
                    time_s: v.times_s.get(k).copied().unwrap_or(f64::NAN),
                    reason: e.to_string(),
                });
            }
        }
    }
    Ok(())
}

/// Records the first checkpoint's `value` in `seen`; a later one differing
/// from it is an error (its numbers would not be comparable).
fn same<T: PartialEq + std::fmt::Debug>(
    what: &'static str,
    seen: &mut Option<T>,
    value: T,
    ckpt: &Path,
) -> Result<(), EvalError> {
    match seen {
        Some(first) if *first != value => Err(EvalError::Incomparable {
            what,
            first: format!("{first:?}"),
            other: format!("{value:?}"),
            checkpoint: ckpt.to_path_buf(),
        }),
        Some(_) => Ok(()),
        None => {
            *seen = Some(value);
            Ok(())
        }
    }
}

/// The test split of the run a checkpoint belongs to: its training config's
/// data root, and `split.json` next to the `seed-N` folder.
/// A relative data path recorded by a run (before paths were recorded
/// absolute) is resolved against the run folder, never the current one.
pub fn test_split_of(checkpoint: &Path, bad: &BadData) -> Result<Dataset, EvalError> {
    let (meta, dir) = CheckpointMeta::load(checkpoint)?;
    let cfg: TrainConfig = serde_json::from_value(meta.train_config.clone()).map_err(|source| {
        EvalError::TrainConfig {
            checkpoint: checkpoint.to_path_buf(),
            source,
        }
    })?;
    let run_dir = dir.parent().unwrap_or(&dir);
    let split_file = run_dir.join("split.json");
    let recorded = cfg.test_data.clone().unwrap_or(cfg.data.clone());
    let root = match recorded.is_absolute() {
        true => recorded.clone(),
        false => run_dir.join(&recorded),
    };
    if !root.is_dir() {
        return Err(EvalError::NoRecordedData {
            run: run_dir.to_path_buf(),
            recorded,
            resolved: root,
        });
    }
    let data = crate::data::read_dataset(&root, &cfg.reader, bad)?;
    if cfg.test_data.is_some() {
        return Ok(data);
    }
    let s =
        split::Split::load(&split_file).map_err(|source| EvalError::NoRecordedSplit { source })?;
    let test = split::select(&data, &s.test);
    // Test sequences left out as bad data are listed in problems.json; any
    // other absence means another dataset.
    let present: std::collections::BTreeSet<&str> =
        test.sequences.iter().map(|q| q.id.as_str()).collect();
    let problems = bad.problems();
    let missing = s
        .test
        .iter()
        .filter(|id| !present.contains(id.as_str()))
        .filter(|id| !problems.iter().any(|p| p.path.starts_with(root.join(id))))
        .count();
    if missing > 0 {
        return Err(EvalError::NotTheTrainingData {
            missing,
            total: s.test.len(),
            split_file,
            root,
        });
    }
    Ok(test)
}

/// Writes the skipped problems to `out/problems.json` (when there are any).
pub fn write_problems(bad: &BadData, out: &Path) -> Result<(), DataError> {
    let problems = bad.problems();
    if !problems.is_empty() {
        tracing::warn!(
            "{} bad-data problem(s) skipped; listed in {}",
            problems.len(),
            out.join("problems.json").display()
        );
        std::fs::create_dir_all(out).map_err(|source| DataError::Create {
            path: out.to_path_buf(),
            source,
        })?;
        grasp_support::atomic::write_atomic(
            &out.join("problems.json"),
            serde_json::to_string_pretty(&problems)?.as_bytes(),
        )?;
    }
    Ok(())
}
