//! A split's valid frames indexed by row: labels, the rows of each
//! sequence, and where the rows' features come from (cached or decoded).

use crate::data::{self, BadData, Dataset};
use crate::error::Result;
use crate::features::SequenceFeatures;
use candle_core::{Device, Tensor};
use image::RgbImage;

/// Where a split's frame features come from.
pub enum FrameSource {
    /// Frozen mode: cached features, one row per valid frame.
    Cached(Tensor),
    /// From scratch: decoded frames, run through the trained backbone.
    Images(Vec<RgbImage>),
}

/// A split's valid frames, indexed by row.
pub struct SplitFrames {
    pub labels: Vec<u32>,
    /// Rows of each sequence, in frame order.
    pub seq_rows: Vec<Vec<usize>>,
    /// The time (s) of each row of `seq_rows`.
    pub seq_times: Vec<Vec<f64>>,
    pub seq_class: Vec<u32>,
    pub seq_ids: Vec<String>,
    pub source: FrameSource,
}

impl SplitFrames {
    pub fn from_features(data: &Dataset, feats: &[SequenceFeatures], dev: &Device) -> Result<Self> {
        let table = crate::features::FrameTable::build(data, feats);
        let x = Tensor::from_vec(table.x, (table.labels.len(), table.dim.max(1)), dev)?;
        Ok(Self::index(
            data,
            |si, fi| feats[si].valid[fi],
            FrameSource::Cached(x),
        ))
    }

    /// Decodes every frame of `data` at `size` (unreadable ones per policy).
    pub fn from_images(data: &Dataset, size: u32, bad: &BadData) -> Result<Self> {
        let bar = crate::progress::bar(data.sequences.len() as u64, "frames");
        let mut images = Vec::new();
        let mut valid = Vec::new();
        for seq in &data.sequences {
            let mut v = Vec::with_capacity(seq.frames.len());
            for i in 0..seq.frames.len() {
                let img = seq.load_frame(i, bad)?;
                v.push(img.is_some());
                images.extend(img.map(|i| data::augment::resize(&i, size)));
            }
            valid.push(v);
            bar.inc(1);
        }
        bar.finish();
        Ok(Self::index(
            data,
            |si, fi| valid[si][fi],
            FrameSource::Images(images),
        ))
    }

    fn index(data: &Dataset, valid: impl Fn(usize, usize) -> bool, source: FrameSource) -> Self {
        let mut s = SplitFrames {
            labels: Vec::new(),
            seq_rows: Vec::new(),
            seq_times: Vec::new(),
            seq_class: Vec::new(),
            seq_ids: Vec::new(),
            source,
        };
        for (si, seq) in data.sequences.iter().enumerate() {
            let (mut rows, mut times) = (Vec::new(), Vec::new());
            for (fi, label) in seq.labels.iter().enumerate() {
                if valid(si, fi) {
                    rows.push(s.labels.len());
                    times.push(seq.time_s(fi));
                    s.labels.push(label.index() as u32);
                }
            }
            s.seq_rows.push(rows);
            s.seq_times.push(times);
            s.seq_class.push(seq.grasp_class().index() as u32);
            s.seq_ids.push(seq.id.clone());
        }
        s
    }

    /// Replaces each cached row by its trace head's input `[f, m]`, traced
    /// over its sequence's rows in time order (`grasp_model::trace`).
    pub fn trace(&mut self, time_constant_s: f64) -> Result<()> {
        let FrameSource::Cached(x) = &self.source else {
            let why = "the trace head trains on cached features (frozen mode)";
            return Err(crate::error::TrainError::Inconsistent(why));
        };
        let (n, dim) = x.dims2()?;
        let rows: Vec<f32> = x.flatten_all()?.to_vec1()?;
        let mut traced = vec![0f32; n * 2 * dim];
        for (seq, times) in self.seq_rows.iter().zip(&self.seq_times) {
            let mut flat = Vec::with_capacity(seq.len() * dim);
            for &r in seq {
                flat.extend_from_slice(&rows[r * dim..(r + 1) * dim]);
            }
            let out = grasp_model::trace::traced_rows(times, &flat, dim, time_constant_s);
            for (&r, row) in seq.iter().zip(out.chunks_exact(2 * dim)) {
                traced[r * 2 * dim..(r + 1) * 2 * dim].copy_from_slice(row);
            }
        }
        self.source = FrameSource::Cached(Tensor::from_vec(traced, (n, 2 * dim), x.device())?);
        Ok(())
    }

    pub fn frames(&self) -> usize {
        self.labels.len()
    }

    /// Keeps of each sequence the rows a sequence head stepping at `hz`
    /// reads (the frame nearest each tick, `grasp_model::heads::
    /// frames_at_rate`), as evaluation reads a video: a validation set
    /// recorded faster than training's is then scored as it will be read.
    pub fn keep_steps_at(&mut self, hz: f64) {
        for (rows, times) in self.seq_rows.iter_mut().zip(&mut self.seq_times) {
            let steps = grasp_model::heads::frames_at_rate(times, hz);
            *rows = steps.iter().map(|&i| rows[i]).collect();
            *times = steps.iter().map(|&i| times[i]).collect();
        }
    }
}
