//! What `sequence.json` says about a recording: read leniently, since a
//! newer generator may add fields and only those below must be right.

use super::SourceError;
use grasp_model::input::Lens;
use grasp_schema::dataset::SEQUENCE_FILE;
use grasp_schema::taxonomy::{Class, Preshape};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// What `sequence.json` says about a recording, when present.
#[derive(Debug, Clone, Default)]
pub struct SequenceInfo {
    pub fps: Option<f64>,
    /// The sequence's pre-shape label.
    pub preshape: Option<Preshape>,
    /// Per-frame ground truth, in frame order.
    pub labels: Vec<Class>,
    /// `render.center_region`: only the centred square of this fraction of
    /// the shorter side was rendered (the rest is black); None: all of it.
    pub center_region: Option<f64>,
    /// `plan.intrinsics`, the lens a model that crops a fixed angle needs:
    /// None when absent, why it does not parse when present but unusable.
    pub intrinsics: Option<Result<Pinhole, String>>,
    /// The `sequence.json` these come from.
    pub path: Option<PathBuf>,
}

impl SequenceInfo {
    /// The recording's lens, from `plan.intrinsics` (None without one); an
    /// unusable one is an error naming its field.
    pub fn lens(&self) -> Result<Option<Lens>, SourceError> {
        match &self.intrinsics {
            None => Ok(None),
            Some(Err(why)) => Err(SourceError::Intrinsics {
                path: self.record(),
                reason: why.clone(),
            }),
            Some(Ok(k)) => Ok(Some(
                Lens::from_pinhole(k.fx, k.fy, k.width, k.height).map_err(|reason| {
                    SourceError::Lens {
                        path: self.record(),
                        reason,
                    }
                })?,
            )),
        }
    }

    fn record(&self) -> PathBuf {
        self.path
            .clone()
            .unwrap_or_else(|| PathBuf::from(SEQUENCE_FILE))
    }

    /// Refuses a model that looks further out than the recording was
    /// rendered: it would see the black surround. `crop` is the model's
    /// centre crop (None: whole frames).
    pub fn check_crop(&self, crop: Option<f64>, dir: &Path) -> Result<(), SourceError> {
        let why = self
            .center_region
            .and_then(|region| grasp_schema::dataset::crop_outside_region(region, crop));
        match why {
            Some(reason) => Err(SourceError::CropOutside {
                dir: dir.to_path_buf(),
                reason,
            }),
            None => Ok(()),
        }
    }
}

/// The part of `plan.intrinsics` a lens needs.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct Pinhole {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
}

/// Reads the fields the runtime needs from `sequence.json`, leniently: a
/// newer generator may add fields, and only these must be right.
pub(super) fn read_sequence_json(path: &Path) -> Result<(Vec<PathBuf>, SequenceInfo), SourceError> {
    let text = std::fs::read_to_string(path).map_err(|source| SourceError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let value = serde_json::from_str(&text).map_err(|source| SourceError::Json {
        path: path.to_path_buf(),
        source,
    })?;
    let record = Record { path, value };
    let files = record.frame_files()?;
    let info = SequenceInfo {
        fps: record.fps()?,
        preshape: record.plan("preshape").and_then(|p| from_value(p).ok()),
        labels: record.labels(),
        center_region: record.center_region()?,
        intrinsics: record.intrinsics(),
        path: Some(path.to_path_buf()),
    };
    Ok((files, info))
}

/// A parsed `sequence.json`.
struct Record<'a> {
    path: &'a Path,
    value: serde_json::Value,
}

impl Record<'_> {
    fn bad(&self, field: impl Into<String>, problem: &'static str) -> SourceError {
        SourceError::Field {
            path: self.path.to_path_buf(),
            field: field.into(),
            problem,
        }
    }

    /// `plan.KEY`.
    fn plan(&self, key: &str) -> Option<&serde_json::Value> {
        self.value.get("plan")?.get(key)
    }

    fn frame_files(&self) -> Result<Vec<PathBuf>, SourceError> {
        let list = self
            .value
            .get("frame_files")
            .and_then(|f| f.as_array())
            .ok_or_else(|| self.bad("frame_files", "is missing or not a list"))?;
        list.iter()
            .enumerate()
            .map(|(i, f)| {
                f.as_str()
                    .map(PathBuf::from)
                    .ok_or_else(|| self.bad(format!("frame_files[{i}]"), "is not a string"))
            })
            .collect()
    }

    fn fps(&self) -> Result<Option<f64>, SourceError> {
        match self.plan("fps") {
            None => Ok(None),
            Some(f) => f
                .as_f64()
                .map(Some)
                .ok_or_else(|| self.bad("plan.fps", "is not a number")),
        }
    }

    /// Per-frame classes; frames without a readable one are left out.
    fn labels(&self) -> Vec<Class> {
        let frames = self.plan("frames").and_then(|f| f.as_array());
        frames.map_or_else(Vec::new, |frames| {
            frames
                .iter()
                .filter_map(|f| from_value(f.get("class")?).ok())
                .collect()
        })
    }

    fn center_region(&self) -> Result<Option<f64>, SourceError> {
        let region = self
            .value
            .get("render")
            .and_then(|r| r.get("center_region"));
        match region {
            None => Ok(None),
            Some(c) => c
                .as_f64()
                .filter(|c| *c > 0.0 && *c <= 1.0)
                .map(Some)
                .ok_or_else(|| self.bad("render.center_region", "is not a fraction in (0, 1]")),
        }
    }

    /// Kept unparsed when wrong: only a model that crops a fixed angle
    /// needs the lens ([`SequenceInfo::lens`]).
    fn intrinsics(&self) -> Option<Result<Pinhole, String>> {
        let k = self.plan("intrinsics").filter(|k| !k.is_null())?;
        Some(Pinhole::deserialize(k).map_err(|e| e.to_string()))
    }
}

fn from_value<T: serde::de::DeserializeOwned>(v: &serde_json::Value) -> serde_json::Result<T> {
    serde_json::from_value(v.clone())
}
