//! What can go wrong in training and evaluation, one enum per concept: a
//! recipe or option ([`ConfigError`]), a dataset on disk ([`DataError`]),
//! the feature cache ([`FeatureError`]), training ([`TrainError`]),
//! evaluation ([`EvalError`]), summaries ([`SummaryError`]) and plots
//! ([`PlotError`]). Every message names the file, the field or the object
//! it is about. A cause (an I/O, tensor or JSON error) is the error's
//! source, which the binary prints after it (`cannot read X: No such file
//! or directory`). Where the cause is the diagnosis it is in the message
//! instead, so that `to_string()` tells all: a parser's message (as
//! `reason`, like grasp-model's `Corrupt`), and a model's or input's error
//! that a step wraps (kept typed in its own field, not as a source, so the
//! binary does not print it twice).

use grasp_model::error::ModelError;
use grasp_model::input::InputError;
use grasp_schema::taxonomy::Preshape;
use grasp_support::atomic::WriteError;
use grasp_support::error_chain as chain;
use std::path::{Path, PathBuf};

/// A recipe, a configuration or an option that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// A value out of range, or settings that do not go together. `field`
    /// is the setting at fault as a recipe names it (`views.count`,
    /// `fine_tune.blocks`); `reason` names it too.
    #[error("{reason}")]
    Invalid { field: &'static str, reason: String },
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file that is not what it should hold (`what`: config, list).
    #[error("invalid {what} {}: {reason}", path.display())]
    Parse {
        what: &'static str,
        path: PathBuf,
        reason: String,
    },
    /// A recipe file or `--set` that does not read (missing, not TOML, not
    /// KEY=VALUE); `reason` is grasp-support's, naming the file or `--set`.
    #[error("{}{reason}", in_recipe(recipe.as_deref()))]
    Layers {
        recipe: Option<PathBuf>,
        reason: String,
    },
    /// A resolved recipe whose fields are not [`crate::config::TrainConfig`]'s
    /// (`from`: "recipe FILE with --set", "the default recipe").
    #[error("{from}: {reason}")]
    Fields { from: String, reason: String },
}

fn in_recipe(recipe: Option<&Path>) -> String {
    recipe.map_or_else(String::new, |p| format!("recipe {}: ", p.display()))
}

impl ConfigError {
    pub fn invalid(field: &'static str, reason: impl Into<String>) -> Self {
        ConfigError::Invalid {
            field,
            reason: reason.into(),
        }
    }
}

/// A dataset on disk that cannot be read, split or written.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error("cannot list {}", path.display())]
    List {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot create {}", path.display())]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write {}", path.display())]
    WriteImage {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error(transparent)]
    Atomic(#[from] WriteError),
    /// A file that is not what it should hold (`what`: split file).
    #[error("invalid {what} {}: {reason}", path.display())]
    Parse {
        what: &'static str,
        path: PathBuf,
        reason: String,
    },
    /// A problem under `on_bad_data = fail`: an unreadable image, a
    /// sequence without labels or frames.
    #[error(
        "bad data: {}: {reason} (to leave it out: eval --on-bad-data skip, train --set on_bad_data=skip)",
        path.display()
    )]
    Bad { path: PathBuf, reason: String },
    /// A sequence (its `sequence.json` or folder) or a dataset that cannot
    /// be used as asked: a crop outside what was rendered, no lens for a
    /// fixed-angle crop, a test world among training's sequences.
    #[error("{}: {reason}", path.display())]
    Invalid { path: PathBuf, reason: String },
    /// The reader's crop or lens options.
    #[error(transparent)]
    Input(#[from] InputError),
    /// A frame the crop cannot be cut from (its size, the lens).
    #[error("{}: {}", path.display(), chain(input))]
    Crop { path: PathBuf, input: InputError },
    #[error("no sequences found under {}", root.display())]
    NoSequences { root: PathBuf },
    #[error(
        "the validation split is empty: add sequences, raise split.val_fraction or pass --val-data"
    )]
    EmptyValidation,
    /// A training split without some pre-shapes; `reason` describes it.
    #[error(
        "{reason}. Add sequences of every pre-shape, or train anyway with --set allow_missing_classes=true"
    )]
    MissingClasses {
        missing: Vec<Preshape>,
        reason: String,
    },
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// The feature cache: computing, checking and storing a sequence's features.
#[derive(Debug, thiserror::Error)]
pub enum FeatureError {
    #[error(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// (The model's error is boxed: it would double the size of every
    /// `Result` of the cache.)
    #[error("feature extraction failed in {}: {}", dir.display(), chain(model))]
    Extract {
        dir: PathBuf,
        model: Box<ModelError>,
    },
    #[error(transparent)]
    NonFinite(#[from] NonFinite),
    /// A cache entry that cannot be used (it is recomputed).
    #[error("{}: {reason}", path.display())]
    Corrupt { path: PathBuf, reason: String },
    #[error("cannot write {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: candle_core::Error,
    },
    #[error(transparent)]
    Atomic(#[from] WriteError),
    #[error(transparent)]
    Candle(#[from] candle_core::Error),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// A value that training or the cache cannot go on from (NaN, infinity):
/// `what` it is, and `at` where it was found ("in epoch 3, batch 0 ...").
#[derive(Debug, thiserror::Error)]
#[error("non-finite {what} ({value}) {at}")]
pub struct NonFinite {
    pub what: &'static str,
    pub value: f64,
    pub at: String,
}

/// Training a model, from its backbone to its checkpoints.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A seed's folder that already holds a checkpoint, and no
    /// `--overwrite`.
    #[error(
        "{} already holds a checkpoint (best.json): pass --overwrite to train over it, or \
         choose another --out",
        dir.display()
    )]
    CheckpointExists { dir: PathBuf },
    #[error(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    Features(#[from] FeatureError),
    /// The run's evaluation on its test split (boxed: it holds most of
    /// what this enum holds).
    #[error(transparent)]
    Eval(Box<EvalError>),
    #[error(transparent)]
    NonFinite(#[from] NonFinite),
    #[error("cannot use checkpoint {} as a backbone: {}", path.display(), chain(model))]
    CheckpointBackbone {
        path: PathBuf,
        model: Box<ModelError>,
    },
    #[error(
        "weights file {}: neither torchvision's MobileNetV2 (features.0.0.weight) nor \
         EfficientNet-Lite0/1/2 (_conv_stem.weight and the Lite blocks)",
        path.display()
    )]
    UnknownArchitecture { path: PathBuf },
    /// A tensor operation that failed in a named step.
    #[error("{context}")]
    Tensors {
        context: &'static str,
        #[source]
        source: candle_core::Error,
    },
    /// Frames or a network in a state the trainer never builds for this
    /// step (a bug, not a user error).
    #[error("{0}")]
    Inconsistent(&'static str),
    #[error("cannot create {}", path.display())]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Boxed, as the model's error is most of this enum's size.
    #[error(transparent)]
    Model(Box<ModelError>),
    #[error(transparent)]
    Candle(#[from] candle_core::Error),
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Toml(#[from] toml::ser::Error),
}

impl From<ModelError> for TrainError {
    fn from(e: ModelError) -> Self {
        TrainError::Model(Box::new(e))
    }
}

impl From<EvalError> for TrainError {
    fn from(e: EvalError) -> Self {
        TrainError::Eval(Box::new(e))
    }
}

/// Evaluating checkpoints and writing their report.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    Features(#[from] FeatureError),
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// Checkpoints whose numbers would not be comparable: `what` differs
    /// (the first checkpoint's and `checkpoint`'s values).
    #[error(
        "cannot aggregate checkpoints with different {what}: {first} and {other} ({})",
        checkpoint.display()
    )]
    Incomparable {
        what: &'static str,
        first: String,
        other: String,
        checkpoint: PathBuf,
    },
    #[error("no video has a frame in the window ({window}): nothing to score")]
    EmptyWindow { window: String },
    /// The same checkpoint given twice (by the same or another path).
    #[error(
        "checkpoint {} is given twice (also as {}): it would count as two seeds",
        checkpoint.display(),
        first.display()
    )]
    DuplicateCheckpoint { first: PathBuf, checkpoint: PathBuf },
    /// A checkpoint whose class list is not the five classes in index
    /// order: its outputs would be scored as other classes.
    #[error(
        "checkpoint {}: classes {classes:?} are not power, lateral, pinch, pinch3, no_grasp in \
         index order; its outputs cannot be scored",
        checkpoint.display()
    )]
    Classes {
        checkpoint: PathBuf,
        classes: Vec<String>,
    },
    /// A model output that is not a probability distribution (NaN, inf).
    #[error(
        "checkpoint {}: invalid model output on video {video} at {time_s:.3} s ({reason}): \
         the model is broken, nothing is scored",
        checkpoint.display()
    )]
    InvalidOutput {
        checkpoint: PathBuf,
        video: String,
        time_s: f64,
        reason: String,
    },
    #[error("the checkpoint's train_config is not readable ({})", checkpoint.display())]
    TrainConfig {
        checkpoint: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A run's recorded data root that is not there.
    #[error(
        "the run {} was trained on {}{}, which does not exist; pass --data to choose the \
         dataset to evaluate",
        run.display(),
        recorded.display(),
        relative_to_run(recorded, resolved)
    )]
    NoRecordedData {
        run: PathBuf,
        recorded: PathBuf,
        resolved: PathBuf,
    },
    /// A run's `split.json` that cannot be read.
    #[error("pass --data to evaluate on a dataset of your choice")]
    NoRecordedSplit {
        #[source]
        source: DataError,
    },
    #[error(
        "{missing} of the {total} test sequences of {} are not in {}: not the dataset the run \
         was trained on? Pass --data to evaluate on a dataset of your choice",
        split_file.display(),
        root.display()
    )]
    NotTheTrainingData {
        missing: usize,
        total: usize,
        split_file: PathBuf,
        root: PathBuf,
    },
    #[error("cannot create {}", path.display())]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Boxed, as the model's error is most of this enum's size.
    #[error(transparent)]
    Model(Box<ModelError>),
    #[error(transparent)]
    Candle(#[from] candle_core::Error),
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

impl From<ModelError> for EvalError {
    fn from(e: ModelError) -> Self {
        EvalError::Model(Box::new(e))
    }
}

fn relative_to_run(recorded: &Path, resolved: &Path) -> String {
    match recorded.is_absolute() {
        true => String::new(),
        false => format!(" (relative to the run folder: {})", resolved.display()),
    }
}

/// Summarizing reports (`grasp-train summarize`).
#[derive(Debug, thiserror::Error)]
pub enum SummaryError {
    /// A `--report LABEL[=X]:PATH` that does not parse.
    #[error("report `{spec}`: {reason}")]
    Entry { spec: String, reason: String },
    /// A list's `index`-th `[[report]]` (from 1) that cannot be used.
    #[error("{}: report {index} (`{label}`): {reason}", path.display())]
    ListEntry {
        path: PathBuf,
        index: usize,
        label: String,
        reason: String,
    },
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("invalid list {}: {reason}", path.display())]
    List { path: PathBuf, reason: String },
    #[error("report `{label}`: cannot read {}", path.display())]
    ReadReport {
        label: String,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("report `{label}`: {} is not a report.json: {reason}", path.display())]
    NotAReport {
        label: String,
        path: PathBuf,
        reason: String,
    },
    #[error("report `{label}`: {} has no aggregate.video_accuracy (no runs?)", path.display())]
    NoRuns { label: String, path: PathBuf },
    #[error("nothing to summarize: give --report LABEL[=X]:PATH or --list FILE.toml")]
    Nothing,
    #[error("report `{label}`: by-condition labels are MODEL/CONDITION (e.g. fc/seated)")]
    NotByCondition { label: String },
    #[error("report `{label}` is given twice")]
    Twice { label: String },
    #[error("choosing the shipped model by its worst test set needs --by-condition")]
    ShipNeedsConditions,
    #[error("model {model} has no report on test set {set}: every model is judged on every set")]
    MissingSet { model: String, set: String },
    #[error(
        "report `{label}` ({path}) has no hand's decision (written by an older grasp-train \
         eval): evaluate it again to rank models by what the hand would do"
    )]
    NoHandDecision { label: String, path: PathBuf },
    #[error(
        "no model can ship: the hand classifies frame by frame and every head here reads \
         sequences ({heads}); add a model with an FC head"
    )]
    NothingShippable { heads: String },
    #[error("report `{label}`: x = {x} cannot go on a log axis")]
    LogAxis { label: String, x: f64 },
    #[error("cannot create {}", path.display())]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Plot(#[from] PlotError),
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// Drawing or encoding a plot.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// plotters' error, as its Debug text (its Display says less).
    #[error("plot: {0}")]
    Draw(String),
    #[error("plot buffer size")]
    Buffer,
    #[error(transparent)]
    Encode(#[from] image::ImageError),
}

pub type Result<T, E = TrainError> = std::result::Result<T, E>;
