//! Lab experiment for issue 57's context lever: up close the recipe's
//! 18.3-degree crop spans a centimetre or two of the part, so the head also
//! sees a wider crop through the same frozen backbone (two scales, their
//! features side by side). Heads on the narrow crop alone (the control), the
//! wide one alone and both, trained alike, each view damped as the recipe
//! does, scored on every world by the hand's decision (`hannes-run`'s default
//! policy) and the per-video vote, 3 seeds.
//!
//! The frames must be rendered wide enough for the wider crop (the main job
//! with `--render-set render.center_region=0.7`); a crop is cut to what was
//! rendered, so a wider angle than the region holds is silently the region.
//!
//! ```sh
//! cargo run --release -p two-scale -- --config runs/wide70/model-fc/config.toml \
//!   --context-deg 25 --out runs/wide70/lab/two-scale --test default=runs/wide70/data/test-default ...
//! ```

mod fit;
mod score;

use anyhow::{bail, ensure, Context, Result};
use candle_core::{Device, Tensor};
use clap::Parser;
use grasp_model::backbone::Backbone;
use grasp_model::input::Crop;
use std::path::{Path, PathBuf};
use trainer::config::TrainConfig;
use trainer::data::{BadData, Dataset};
use trainer::features::FeatureCache;
use trainer::plan::{Extraction, RunPlan};
use trainer::train::{FrameSource, SplitFrames, ViewDamping};

#[derive(Parser)]
struct Args {
    /// The main job's FC run config (`model-fc/config.toml`): the data, the
    /// reader's crop, the views and their damping, the backbone.
    #[arg(long)]
    config: PathBuf,
    /// The wider crop's full angle, in degrees.
    #[arg(long, default_value_t = 25.0)]
    context_deg: f64,
    /// The feature cache (default: the config's).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Test sets, NAME=DIR.
    #[arg(long)]
    test: Vec<String>,
    #[arg(long, default_value_t = 3)]
    seeds: u64,
    #[arg(long)]
    out: PathBuf,
}

/// A split's frames with each scale's features, one row per valid frame.
pub struct Split {
    pub frames: SplitFrames,
    pub narrow: Tensor,
    pub wide: Tensor,
}

/// The recipe's view damping, fitted on each scale's features apart.
struct Damping {
    narrow: Option<ViewDamping>,
    wide: Option<ViewDamping>,
}

struct Extractor<'a> {
    backbone: &'a Backbone,
    cache: FeatureCache,
    context: Crop,
    bad: BadData,
}

fn main() -> Result<()> {
    tracing_subscriber::fmt().with_env_filter("info").init();
    let args = Args::parse();
    let cfg = TrainConfig::from_toml_file(&args.config)?;
    let plan = RunPlan::resolve(&cfg)?;
    let Extraction::Frozen {
        backbone,
        views,
        damping,
        ..
    } = &plan.features.extraction
    else {
        bail!("{}: not a frozen run", args.config.display());
    };
    let ex = Extractor {
        backbone,
        cache: match &args.cache_dir {
            Some(dir) => FeatureCache::new(dir, plan.cache.batch),
            None => plan.cache.open(),
        },
        context: Crop::AngleDeg(args.context_deg),
        bad: BadData::new(plan.on_bad_data),
    };
    let splits = trainer::train::load_splits(&plan.data, &ex.bad)?;
    let train_views = trainer::data::view::with_views(&splits.train, &views.config, views.seed);
    let mut train = ex.split(&train_views)?;
    let damp = Damping::fit(&train, splits.train.sequences.len(), *damping)?;
    damp.apply(&mut train)?;
    let mut val = ex.split(&splits.val)?;
    damp.apply(&mut val)?;
    let models = score::Models::fit(&train, &val, args.seeds)?;
    std::fs::create_dir_all(&args.out)?;
    let mut table = score::Table::default();
    for t in &args.test {
        let (name, dir) = t.split_once('=').context("--test NAME=DIR")?;
        let mut data = trainer::data::read_dataset(Path::new(dir), &plan.data.reader, &ex.bad)?;
        data.trim_lead_ins();
        let mut set = ex.split(&data)?;
        damp.apply(&mut set)?;
        table.add(name, &models.score(&set, &data)?);
        let md = table.markdown();
        println!("{md}");
        std::fs::write(args.out.join("result.md"), md)?;
    }
    Ok(())
}

impl Extractor<'_> {
    /// Both scales' features of `data` (its sequences' own crop, the
    /// recipe's, and the context crop).
    fn split(&self, data: &Dataset) -> Result<Split> {
        let (frames, narrow) = self.features(data)?;
        let mut wide_data = data.clone();
        wide_data
            .sequences
            .iter_mut()
            .for_each(|s| s.crop = self.context);
        let (wide_frames, wide) = self.features(&wide_data)?;
        ensure!(
            wide_frames.seq_rows == frames.seq_rows,
            "the two scales read different frames of {}",
            data.root.display()
        );
        Ok(Split {
            frames,
            narrow,
            wide,
        })
    }

    fn features(&self, data: &Dataset) -> Result<(SplitFrames, Tensor)> {
        let feats = self.cache.dataset(self.backbone, data, &self.bad)?;
        let mut frames = SplitFrames::from_features(data, &feats, &Device::Cpu)?;
        let FrameSource::Cached(x) =
            std::mem::replace(&mut frames.source, FrameSource::Images(vec![]))
        else {
            bail!("frozen features are cached");
        };
        Ok((frames, x))
    }
}

impl Damping {
    fn fit(train: &Split, originals: usize, strength: f64) -> Result<Damping> {
        if strength <= 0.0 {
            return Ok(Damping {
                narrow: None,
                wide: None,
            });
        }
        let of = |x: &Tensor| -> Result<Option<ViewDamping>> {
            let frames = SplitFrames {
                labels: train.frames.labels.clone(),
                seq_rows: train.frames.seq_rows.clone(),
                seq_times: vec![],
                seq_class: vec![],
                seq_ids: vec![],
                source: FrameSource::Cached(x.clone()),
            };
            Ok(ViewDamping::from_views(&frames, originals, strength)?)
        };
        Ok(Damping {
            narrow: of(&train.narrow)?,
            wide: of(&train.wide)?,
        })
    }

    fn apply(&self, split: &mut Split) -> Result<()> {
        if let Some(d) = &self.narrow {
            split.narrow = d.apply(&split.narrow)?;
        }
        if let Some(d) = &self.wide {
            split.wide = d.apply(&split.wide)?;
        }
        Ok(())
    }
}
