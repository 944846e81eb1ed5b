//! Datasets of reach-to-grasp sequences: the reader for the generator's and
//! the authors' layouts, bad-data reporting, splits and augmentation.

pub mod augment;
pub mod bad;
pub mod coverage;
pub mod images;
pub mod probe;
pub mod reader;
pub mod split;
pub mod style;
pub mod synthetic;
pub mod view;

pub use bad::{BadData, OnBadData};
pub use reader::{read_dataset, ReaderOptions};

use crate::error::DataError;
use grasp_schema::taxonomy::{Class, Preshape};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Where the labels of a sequence came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelSource {
    /// Per-frame labels from the generator's `sequence.json`.
    SequenceJson,
    /// The authors' real data: the folder's pre-shape, with the last 0.5 s
    /// labelled `no_grasp`.
    PreshapeFolder,
}

/// One reach-to-grasp sequence with its per-frame labels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sequence {
    /// Unique id: the sequence folder relative to the dataset root.
    pub id: String,
    /// The sequence folder (`.../Wrist_d435/rgbNNNNN`).
    pub dir: PathBuf,
    pub category: String,
    pub object: String,
    /// Object part (`sequence.json`'s key); absent for the authors' real
    /// data, which has no part annotation.
    pub part: Option<String>,
    pub preshape: Preshape,
    /// `default`, `fast`, ... for generated data; `real` for the authors'.
    pub condition: String,
    pub fps: f64,
    pub frames: Vec<PathBuf>,
    pub labels: Vec<Class>,
    pub label_source: LabelSource,
    /// The model's centre crop (its input record's, `ReaderOptions::crop`).
    #[serde(default)]
    pub crop: grasp_model::input::Crop,
    /// The camera's lens, which a fixed-angle crop is cut through: the
    /// `sequence.json`'s intrinsics, or the one given for real data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lens: Option<grasp_model::input::Lens>,
    /// Leading frames in which the wrist camera does not see the target
    /// (`SequencePlan::lead_in_frames`; 0 for the authors' data).
    #[serde(default)]
    pub lead_in: usize,
    /// Frames dropped from the front by [`Sequence::trim_lead_in`]: frame
    /// `i` is the recording's frame `i + first_frame`.
    #[serde(default)]
    pub first_frame: usize,
    /// Frames rendered only in their centre (`[render] center_region` < 1):
    /// the rendered square's side, a fraction of the shorter side. Augmented
    /// views stay inside it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rendered_region: Option<f64>,
    /// The backbone's input square is denoised first
    /// (`ReaderOptions::denoise`, `grasp_model::input::denoise`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub denoise: bool,
    /// Why the sequence belongs to a test world that training never draws
    /// from (`render.world = "foreign"`, `dataset.held_out = "reach"`);
    /// None for training's own world and for real data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_world: Option<String>,
    /// An augmented view of the frames (frozen mode's training
    /// augmentation, [`view::with_views`]); None: the frames as they are.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<view::ViewJitter>,
    /// Extra sensor degradation of every frame, before the crop (a sensor
    /// view's); None: the frames as rendered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe: Option<probe::SensorProbe>,
    /// Block outputs restyled in the frozen backbone (a style view,
    /// [`view::with_views`]); None: the backbone as it is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub style: Option<style::StyleDraw>,
}

impl Sequence {
    /// The stratum of the split: the object-part pair (the object and
    /// pre-shape folder when the part is unknown).
    pub fn stratum(&self) -> String {
        let part = self
            .part
            .as_deref()
            .unwrap_or(self.preshape.authors_folder());
        format!("{}/{}", self.object, part)
    }

    /// Frame `i`, decoded, probed and centre-cropped as the reader was
    /// told.
    pub fn load_frame(
        &self,
        i: usize,
        bad: &BadData,
    ) -> Result<Option<image::RgbImage>, DataError> {
        let Some(mut img) = images::load_frame(&self.frames[i], bad)? else {
            return Ok(None);
        };
        if let Some(p) = &self.probe {
            img = p.apply(&img, &format!("{}/{}", self.id, i + self.first_frame));
        }
        let fraction = self
            .crop_fraction(img.width(), img.height())
            .map_err(|input| DataError::Crop {
                path: self.frames[i].clone(),
                input,
            })?;
        let input = match &self.view {
            None => match fraction {
                Some(f) => images::center_crop(&img, f),
                None => img,
            },
            Some(v) => v.apply(&img, fraction, self.rendered_region),
        };
        // After the probe, which stands for the camera, and the crop, so
        // that only what the backbone sees is filtered.
        Ok(Some(grasp_model::input::filter(input, self.denoise)))
    }

    /// The fraction of a `width` x `height` frame's shorter side the
    /// backbone sees: the model's crop through the sequence's lens at the
    /// frame's own size ([`grasp_model::input::Crop::fraction`]), cut to
    /// what was rendered.
    pub fn crop_fraction(
        &self,
        width: u32,
        height: u32,
    ) -> Result<Option<f64>, grasp_model::input::InputError> {
        let fraction = self.crop.fraction(self.lens.as_ref(), width, height)?;
        Ok(fraction.map(|f| f.min(self.rendered_region.unwrap_or(1.0))))
    }

    /// The sequence's grasp class (its pre-shape).
    pub fn grasp_class(&self) -> Class {
        Class::from(self.preshape)
    }

    /// Time of frame `i` since the start of the recording, in seconds.
    pub fn time_s(&self, i: usize) -> f64 {
        (i + self.first_frame) as f64 / self.fps
    }

    /// Drops the lead-in (the frames before the target enters the view), as
    /// the paper trims its from-ground videos at inference time. Returns the
    /// number of frames dropped.
    pub fn trim_lead_in(&mut self) -> usize {
        let n = self.lead_in.min(self.frames.len());
        self.frames.drain(..n);
        self.labels.drain(..n.min(self.labels.len()));
        self.first_frame += n;
        self.lead_in = 0;
        n
    }
}

/// A dataset: the readable sequences of one root, in a stable order.
#[derive(Debug, Clone, Default)]
pub struct Dataset {
    pub root: PathBuf,
    pub sequences: Vec<Sequence>,
}

impl Dataset {
    /// Whether this is the authors' real data (labels from folders), which
    /// selects the paper's real-data batch size.
    pub fn is_real(&self) -> bool {
        !self.sequences.is_empty()
            && self
                .sequences
                .iter()
                .all(|s| s.label_source == LabelSource::PreshapeFolder)
    }

    /// Trims every sequence's lead-in ([`Sequence::trim_lead_in`]):
    /// returns (videos trimmed, frames dropped).
    pub fn trim_lead_ins(&mut self) -> (usize, usize) {
        let dropped: Vec<usize> = self
            .sequences
            .iter_mut()
            .map(|s| s.trim_lead_in())
            .collect();
        (
            dropped.iter().filter(|n| **n > 0).count(),
            dropped.iter().sum(),
        )
    }

    /// Several test draws as one dataset: their sequences in order, each id
    /// prefixed with its draw's root when there is more than one (two draws
    /// of one config share relative folder names). The root is the first's.
    pub fn pool(mut datasets: Vec<Dataset>) -> Dataset {
        if datasets.len() == 1 {
            return datasets.remove(0);
        }
        let root = datasets.first().map(|d| d.root.clone()).unwrap_or_default();
        let sequences = datasets
            .into_iter()
            .flat_map(|d| {
                let prefix = d.root.display().to_string();
                d.sequences.into_iter().map(move |mut s| {
                    s.id = format!("{prefix}/{}", s.id);
                    s
                })
            })
            .collect();
        Dataset { root, sequences }
    }

    pub fn frame_count(&self) -> usize {
        self.sequences.iter().map(|s| s.frames.len()).sum()
    }

    /// Objects that have more than one grasp pre-shape in this dataset
    /// (the paper's "multi-grasp" objects).
    pub fn multi_grasp_objects(&self) -> std::collections::BTreeSet<String> {
        let mut by_object: std::collections::BTreeMap<&str, std::collections::BTreeSet<Preshape>> =
            Default::default();
        for s in &self.sequences {
            by_object.entry(&s.object).or_default().insert(s.preshape);
        }
        by_object
            .into_iter()
            .filter(|(_, p)| p.len() > 1)
            .map(|(o, _)| o.to_string())
            .collect()
    }
}
