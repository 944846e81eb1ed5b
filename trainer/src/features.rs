//! The on-disk feature cache of the frozen-backbone mode (the paper's): the
//! backbone's feature vector of every frame, computed once and reused by
//! every later run that uses the same weights and preprocessing.
//!
//! Layout: `CACHE/<key>/<sequence hash>.safetensors`, where `key` hashes the
//! extractor (the weights file's SHA-256, width multiplier, input size, mean,
//! std) and the sequence hash covers the frame files' paths, sizes and
//! modification times, so re-rendered frames are never served stale
//! features. Each file holds `features` (valid frames x dim, f32) and `valid`
//! (one u8 per frame: 0 where the image was unreadable and skipped). Writes
//! go to a temporary file renamed into place, so an interrupted run leaves no
//! partial entry and concurrent runs never read one.

use crate::data::{BadData, Dataset, Sequence};
use crate::error::{FeatureError, NonFinite};
use candle_core::{DType, Device, Tensor};
use grasp_model::extractor::FeatureExtractor;
use grasp_model::hashing::{hex, sha256_hex};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Features of one sequence: rows for the readable frames only.
#[derive(Debug, Clone)]
pub struct SequenceFeatures {
    /// `(valid frames, dim)` row-major.
    pub rows: Vec<f32>,
    pub dim: usize,
    /// One flag per frame of the sequence.
    pub valid: Vec<bool>,
}

impl SequenceFeatures {
    pub fn valid_count(&self) -> usize {
        self.valid.iter().filter(|v| **v).count()
    }
}

pub struct FeatureCache {
    pub dir: PathBuf,
    /// Frames per backbone forward pass.
    pub batch: usize,
}

impl FeatureCache {
    pub fn new(dir: impl Into<PathBuf>, batch: usize) -> Self {
        FeatureCache {
            dir: dir.into(),
            batch: batch.max(1),
        }
    }

    /// Features of every sequence of `data`, computing and storing the
    /// missing ones (with a progress bar).
    pub fn dataset(
        &self,
        ex: &dyn FeatureExtractor,
        data: &Dataset,
        bad: &BadData,
    ) -> Result<Vec<SequenceFeatures>, FeatureError> {
        let bar = crate::progress::bar(data.sequences.len() as u64, "features");
        let mut out: Vec<Option<SequenceFeatures>> = vec![None; data.sequences.len()];
        let (mut hits, mut computed) = (0usize, 0usize);
        // A sequence's views (style views restyle inside the backbone) come
        // right after it, so each frame is prepared (decoded, cropped,
        // denoised) once for all of them.
        let mut order: Vec<usize> = (0..data.sequences.len()).collect();
        order.sort_by(|&a, &b| data.sequences[a].dir.cmp(&data.sequences[b].dir));
        let mut prepared = PreparedFrames::default();
        for i in order {
            let seq = &data.sequences[i];
            prepared.keep_only(&seq.dir);
            let (f, hit) = self.sequence_with(ex, seq, bad, &mut prepared)?;
            if hit {
                hits += 1;
            } else {
                computed += 1;
            }
            out[i] = Some(f);
            bar.set_message(format!("{hits} cached, {computed} computed"));
            bar.inc(1);
        }
        bar.finish();
        Ok(out
            .into_iter()
            .map(|f| f.expect("every sequence visited"))
            .collect())
    }

    /// Features of one sequence and whether they came from the cache.
    pub fn sequence(
        &self,
        ex: &dyn FeatureExtractor,
        seq: &Sequence,
        bad: &BadData,
    ) -> Result<(SequenceFeatures, bool), FeatureError> {
        self.sequence_with(ex, seq, bad, &mut PreparedFrames::default())
    }

    fn sequence_with(
        &self,
        ex: &dyn FeatureExtractor,
        seq: &Sequence,
        bad: &BadData,
        prepared: &mut PreparedFrames,
    ) -> Result<(SequenceFeatures, bool), FeatureError> {
        let path = self.entry_path(ex, seq)?;
        if path.is_file() {
            match read_entry(&path, ex.feature_dim(), seq.frames.len()) {
                Ok(f) => {
                    for (frame, ok) in seq.frames.iter().zip(&f.valid) {
                        if !ok {
                            bad.report(frame, "unreadable image (recorded in the feature cache)")?;
                        }
                    }
                    return Ok((f, true));
                }
                Err(e) => tracing::warn!("recomputing bad cache entry {e}"),
            }
        }
        let f = compute(ex, seq, bad, self.batch, prepared)?;
        write_entry(&path, &f)?;
        Ok((f, false))
    }

    fn entry_path(
        &self,
        ex: &dyn FeatureExtractor,
        seq: &Sequence,
    ) -> Result<PathBuf, FeatureError> {
        let key = sha256_hex(ex.id().as_bytes())[..24].to_string();
        Ok(self
            .dir
            .join(key)
            .join(format!("{}.safetensors", sequence_hash(seq)?)))
    }
}

/// Hash of the frame files' absolute paths, sizes and modification times,
/// and of the centre crop, augmented view, sensor probe and denoising the
/// backbone sees.
fn sequence_hash(seq: &Sequence) -> Result<String, FeatureError> {
    let mut h = Sha256::new();
    if seq.crop != grasp_model::input::Crop::Whole {
        h.update(b"crop");
        h.update(serde_json::to_vec(&seq.crop)?);
        if let Some(lens) = &seq.lens {
            h.update(b"lens");
            h.update(serde_json::to_vec(lens)?);
        }
        // A crop is cut to the rendered region.
        if let (Some(r), None) = (seq.rendered_region, &seq.view) {
            h.update(b"crop_region");
            h.update(r.to_le_bytes());
        }
    }
    if let Some(v) = &seq.view {
        h.update(b"view");
        h.update(serde_json::to_vec(v)?);
        if let Some(r) = seq.rendered_region {
            h.update(b"rendered_region");
            h.update(r.to_le_bytes());
        }
    }
    if let Some(p) = &seq.probe {
        h.update(b"probe");
        h.update(serde_json::to_vec(p)?);
    }
    if let Some(s) = &seq.style {
        h.update(b"style");
        h.update(serde_json::to_vec(s)?);
    }
    if seq.denoise {
        h.update(b"denoise");
    }
    for f in &seq.frames {
        let abs = std::fs::canonicalize(f).unwrap_or_else(|_| f.clone());
        h.update(abs.to_string_lossy().as_bytes());
        h.update([0]);
        if let Ok(meta) = std::fs::metadata(f) {
            h.update(meta.len().to_le_bytes());
            if let Ok(t) = meta.modified() {
                let d = t.duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
                h.update(d.as_nanos().to_le_bytes());
            }
        }
    }
    Ok(hex(&h.finalize())[..32].to_string())
}

/// The backbone inputs of one sequence folder's frames, shared by the
/// sequence and its views: a view that changes no pixel before the backbone
/// (a style view) reads the frames its sequence prepared. The key holds
/// everything [`Sequence::load_frame`] reads, so equal keys give equal
/// images.
#[derive(Default)]
struct PreparedFrames {
    dir: PathBuf,
    images: HashMap<String, Option<image::RgbImage>>,
}

impl PreparedFrames {
    /// Forgets the frames of any other folder.
    fn keep_only(&mut self, dir: &Path) {
        if self.dir != dir {
            self.dir = dir.to_path_buf();
            self.images.clear();
        }
    }

    fn key(seq: &Sequence, frame: usize) -> String {
        format!(
            "{}|{:?}|{:?}|{:?}|{:?}|{:?}|{}|{}",
            seq.frames[frame].display(),
            seq.probe,
            seq.view,
            seq.crop,
            seq.lens,
            seq.rendered_region,
            seq.denoise,
            seq.id.split('#').next().unwrap_or_default(),
        )
    }
}

fn compute(
    ex: &dyn FeatureExtractor,
    seq: &Sequence,
    bad: &BadData,
    batch: usize,
    prepared: &mut PreparedFrames,
) -> Result<SequenceFeatures, FeatureError> {
    let dim = ex.feature_dim();
    let mut rows = Vec::with_capacity(seq.frames.len() * dim);
    let mut valid = Vec::with_capacity(seq.frames.len());
    let channels = seq
        .style
        .as_ref()
        .map_or_else(Vec::new, |_| ex.block_channels());
    for (c, chunk) in seq.frames.chunks(batch).enumerate() {
        let mut images = Vec::with_capacity(chunk.len());
        let mut styles = vec![];
        // Decoding, cropping and denoising are per frame: on every core,
        // once per frame for a sequence and its views.
        let keys: Vec<String> = (0..chunk.len())
            .map(|i| PreparedFrames::key(seq, c * batch + i))
            .collect();
        let loaded: Vec<Result<Option<image::RgbImage>, _>> = {
            use rayon::prelude::*;
            let known = &prepared.images;
            (0..chunk.len())
                .into_par_iter()
                .map(|i| match known.get(&keys[i]) {
                    Some(img) => Ok(img.clone()),
                    None => seq.load_frame(c * batch + i, bad),
                })
                .collect()
        };
        for (i, img) in loaded.into_iter().enumerate() {
            let frame = c * batch + i;
            let img = img?;
            prepared.images.insert(keys[i].clone(), img.clone());
            valid.push(img.is_some());
            if let (Some(_), Some(style)) = (&img, &seq.style) {
                styles.push(style.frame_styles(frame + seq.first_frame, &channels)?);
            }
            images.extend(img);
        }
        if images.is_empty() {
            continue;
        }
        let t = match seq.style {
            None => ex.extract(&images),
            Some(_) => ex.extract_styled(&images, &styles),
        }
        .map_err(|e| FeatureError::Extract {
            dir: seq.dir.clone(),
            model: Box::new(e),
        })?;
        let v: Vec<f32> = t.to_dtype(DType::F32)?.flatten_all()?.to_vec1()?;
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(NonFinite {
                what: "feature",
                value: f64::from(v[i]),
                at: format!(
                    "for frame {} of {}",
                    chunk[(i / dim).min(chunk.len() - 1)].display(),
                    seq.dir.display()
                ),
            }
            .into());
        }
        rows.extend(v);
    }
    Ok(SequenceFeatures { rows, dim, valid })
}

/// A cache entry, checked against the sequence (`frames`) and the
/// extractor (`dim`).
fn read_entry(path: &Path, dim: usize, frames: usize) -> Result<SequenceFeatures, FeatureError> {
    let corrupt = |reason: String| FeatureError::Corrupt {
        path: path.to_path_buf(),
        reason,
    };
    let (valid, feats) = load_entry(path).map_err(|e| corrupt(e.to_string()))?;
    let n = valid.iter().filter(|v| **v != 0).count();
    if valid.len() != frames {
        let cached = valid.len();
        return Err(corrupt(format!(
            "{cached} frames cached, {frames} in the sequence"
        )));
    }
    let rows: Vec<f32> = if n == 0 {
        Vec::new()
    } else {
        if feats.dims() != [n, dim] {
            let shape = feats.dims();
            return Err(corrupt(format!(
                "features of shape {shape:?}, expected [{n}, {dim}]"
            )));
        }
        feats
            .flatten_all()
            .and_then(|f| f.to_vec1())
            .map_err(|e| corrupt(e.to_string()))?
    };
    Ok(SequenceFeatures {
        rows,
        dim,
        valid: valid.into_iter().map(|v| v != 0).collect(),
    })
}

/// A cache entry's `valid` flags and `features` tensor.
fn load_entry(path: &Path) -> candle_core::Result<(Vec<u8>, Tensor)> {
    let mut t = candle_core::safetensors::load(path, &Device::Cpu)?;
    let mut take = |name: &str| {
        t.remove(name)
            .ok_or_else(|| candle_core::Error::Msg(format!("no '{name}'")))
    };
    let valid = take("valid")?.to_vec1()?;
    Ok((valid, take("features")?))
}

fn write_entry(path: &Path, f: &SequenceFeatures) -> Result<(), FeatureError> {
    let dev = Device::Cpu;
    let n = f.valid_count();
    let mut map = HashMap::new();
    let features = if n == 0 {
        Tensor::zeros((0, f.dim), DType::F32, &dev)?
    } else {
        Tensor::from_slice(&f.rows, (n, f.dim), &dev)?
    };
    map.insert("features".to_string(), features);
    let valid: Vec<u8> = f.valid.iter().map(|v| u8::from(*v)).collect();
    map.insert(
        "valid".to_string(),
        Tensor::from_vec(valid, f.valid.len(), &dev)?,
    );
    grasp_support::atomic::write_atomic_with(path, |tmp| {
        candle_core::safetensors::save(&map, tmp).map_err(|source| FeatureError::Write {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// Frames of a split flattened for the FC head: one row per valid frame.
#[derive(Debug, Clone, Default)]
pub struct FrameTable {
    pub dim: usize,
    pub x: Vec<f32>,
    pub labels: Vec<u32>,
    /// Index of the frame's sequence and its frame index within it.
    pub seq: Vec<usize>,
    pub frame: Vec<usize>,
}

impl FrameTable {
    pub fn build(data: &Dataset, feats: &[SequenceFeatures]) -> FrameTable {
        let dim = feats.first().map(|f| f.dim).unwrap_or(0);
        let mut t = FrameTable {
            dim,
            ..Default::default()
        };
        for (si, (seq, f)) in data.sequences.iter().zip(feats).enumerate() {
            let mut row = 0;
            for (fi, ok) in f.valid.iter().enumerate() {
                if !ok {
                    continue;
                }
                t.x.extend_from_slice(&f.rows[row * dim..(row + 1) * dim]);
                t.labels.push(seq.labels[fi].index() as u32);
                t.seq.push(si);
                t.frame.push(fi);
                row += 1;
            }
        }
        t
    }

    pub fn len(&self) -> usize {
        self.labels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }
}
