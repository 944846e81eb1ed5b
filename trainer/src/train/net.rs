//! The trainable network (a head, plus the backbone from scratch): its
//! forward pass on a batch of rows or sequences, and the batch's loss.

use super::tail::Tail;
use super::{FrameSource, SplitFrames};
use crate::data;
use crate::error::{Result, TrainError};
use candle_core::{Device, Tensor, D};
use candle_nn::VarMap;
use grasp_model::backbone::Backbone;
use grasp_model::heads::{Head, HeadKind};
use grasp_model::ops::gather::gather_rows;
use image::RgbImage;
use rand::Rng;

/// The trainable network: a head, plus the backbone in from-scratch mode.
pub struct Net {
    pub head: Head,
    pub head_vars: VarMap,
    /// From-scratch backbone and its variables.
    pub backbone: Option<(Backbone, VarMap)>,
    /// Fine-tuned mode's trainable last blocks, on cached activations.
    pub tail: Option<Tail>,
    pub augment: crate::data::augment::AugmentConfig,
    pub tbptt: usize,
    /// The fraction of each training sequence's first frames that its
    /// start is drawn from (LSTM head; 0: whole sequences).
    pub start_crop: f64,
}

impl Net {
    /// The variables trained at the head's learning rate.
    pub(super) fn trainable(&self) -> Vec<candle_core::Var> {
        let mut v = crate::init::trainable_vars(&self.head_vars);
        if let Some((_, vm)) = &self.backbone {
            v.extend(crate::init::trainable_vars(vm));
        }
        v
    }

    /// Fine-tuned mode's block variables, trained at their own rate.
    pub(super) fn tail_trainable(&self) -> Option<Vec<candle_core::Var>> {
        self.tail
            .as_ref()
            .map(|t| crate::init::trainable_vars(&t.vars))
    }

    /// Features `(rows, D)` of `rows` of `frames` (`None`: a zero padding
    /// row, for sequence batches).
    fn features(
        &self,
        frames: &SplitFrames,
        rows: &[Option<usize>],
        train: bool,
        rng: &mut impl Rng,
    ) -> Result<Tensor> {
        match (&frames.source, &self.backbone) {
            (FrameSource::Cached(x), _) => {
                let x = gather_rows(x, rows)?;
                match &self.tail {
                    Some(tail) => tail.forward(&x),
                    None => Ok(x),
                }
            }
            (FrameSource::Images(images), Some((bb, _))) => {
                let size = bb.preprocess.size;
                let present: Vec<usize> = rows.iter().flatten().copied().collect();
                let batch: Vec<RgbImage> = present
                    .iter()
                    .map(|r| {
                        if train {
                            data::augment::augment(&images[*r], size, &self.augment, rng)
                        } else {
                            data::augment::resize(&images[*r], size)
                        }
                    })
                    .collect();
                let x = bb.input(&batch)?;
                let f = bb.net.features(&x, train)?;
                if present.len() == rows.len() {
                    return Ok(f);
                }
                // Padding rows: a zero row appended after the features.
                let zero = Tensor::zeros((1, f.dim(1)?), f.dtype(), f.device())?;
                let with_zero = Tensor::cat(&[&f, &zero], 0)?;
                let mut next = 0u32;
                let index: Vec<u32> = rows
                    .iter()
                    .map(|r| match r {
                        Some(_) => {
                            next += 1;
                            next - 1
                        }
                        None => present.len() as u32,
                    })
                    .collect();
                let index = Tensor::from_vec(index, rows.len(), f.device())?;
                Ok(with_zero.index_select(&index, 0)?)
            }
            (FrameSource::Images(_), None) => {
                let why = "image frames need a trainable backbone";
                Err(TrainError::Inconsistent(why))
            }
        }
    }

    /// Logits and targets (and a padding mask for sequences) of one batch of
    /// units: rows for the FC head, sequences for the LSTM head.
    pub(super) fn forward(
        &self,
        frames: &SplitFrames,
        units: &[usize],
        train: bool,
        rng: &mut impl Rng,
    ) -> Result<Batch> {
        let dev = Device::Cpu;
        match self.head.cfg.kind {
            // A trace head's cached rows are traced already (`prepare`).
            HeadKind::Fc | HeadKind::Trace => {
                let rows: Vec<Option<usize>> = units.iter().map(|r| Some(*r)).collect();
                let x = self.features(frames, &rows, train, rng)?;
                let targets: Vec<u32> = units.iter().map(|r| frames.labels[*r]).collect();
                Ok(Batch {
                    logits: self.head.forward_frames(&x)?,
                    features: x,
                    targets: Tensor::from_vec(targets, units.len(), &dev)?,
                    mask: None,
                })
            }
            HeadKind::Lstm => self.forward_sequences(frames, units, train, rng),
        }
    }

    /// A batch of sequences padded at the end to the longest, `(B, T, D)`.
    fn forward_sequences(
        &self,
        frames: &SplitFrames,
        seqs: &[usize],
        train: bool,
        rng: &mut impl Rng,
    ) -> Result<Batch> {
        let dev = Device::Cpu;
        let crop = if train { self.start_crop } else { 0.0 };
        let seq_rows: Vec<&[usize]> = seqs
            .iter()
            .map(|s| cropped_start(&frames.seq_rows[*s], crop, rng))
            .collect();
        let t_max = seq_rows.iter().map(|r| r.len()).max().unwrap_or(0);
        let (mut rows, mut targets, mut mask) = (Vec::new(), Vec::new(), Vec::new());
        for r in seq_rows {
            let pad = t_max - r.len();
            rows.extend(r.iter().map(|row| Some(*row)));
            rows.extend(std::iter::repeat_n(None, pad));
            targets.extend(r.iter().map(|row| frames.labels[*row]));
            targets.extend(std::iter::repeat_n(0, pad));
            mask.extend(std::iter::repeat_n(1f32, r.len()));
            mask.extend(std::iter::repeat_n(0f32, pad));
        }
        let x = self.features(frames, &rows, train, rng)?;
        let xs = x.reshape((seqs.len(), t_max, x.dim(1)?))?;
        let logits = self.lstm_logits(&xs, train)?;
        let n = seqs.len() * t_max;
        Ok(Batch {
            logits: logits.reshape((n, ()))?,
            features: x,
            targets: Tensor::from_vec(targets, n, &dev)?,
            mask: Some(Tensor::from_vec(mask, n, &dev)?),
        })
    }

    /// LSTM logits `(B, T, C)`; in training with `tbptt > 0` the sequence is
    /// run in chunks whose state is detached, so gradients flow back at most
    /// `tbptt` steps.
    fn lstm_logits(&self, xs: &Tensor, train: bool) -> Result<Tensor> {
        let (b, t, _) = xs.dims3()?;
        let k = self.tbptt;
        if !train || k == 0 || t <= k {
            return Ok(self.head.forward_sequences(xs)?);
        }
        let no_state = TrainError::Inconsistent("the head has no LSTM state");
        let mut state = self.head.zero_state(b, xs)?.ok_or(no_state)?;
        let mut outs = Vec::new();
        for start in (0..t).step_by(k) {
            let len = k.min(t - start);
            let (l, s) = self
                .head
                .forward_chunk(&xs.narrow(1, start, len)?, &state)?;
            outs.push(l);
            state = s.detach();
        }
        Ok(Tensor::cat(&outs, 1)?)
    }

    /// The checkpoint tensor that reads the features: the FC (or trace)
    /// head's weights, or the LSTM's input weights.
    pub(super) fn feature_weight_name(&self) -> &'static str {
        match self.head.cfg.kind {
            HeadKind::Fc | HeadKind::Trace => "head.fc.weight",
            HeadKind::Lstm => "head.lstm.weight_ih_l0",
        }
    }

    /// Tensors of the checkpoint: `head.*`, plus `backbone.*` from scratch
    /// or `tail.*` fine-tuned.
    pub fn tensors(&self) -> Vec<(String, Tensor)> {
        let mut out = Vec::new();
        let mut add = |prefix: &str, vm: &VarMap| {
            let data = vm.data().lock().expect("varmap");
            for (name, var) in data.iter() {
                out.push((format!("{prefix}.{name}"), var.as_tensor().detach()));
            }
        };
        add("head", &self.head_vars);
        if let Some((_, vm)) = &self.backbone {
            add("backbone", vm);
        }
        if let Some(tail) = &self.tail {
            add("tail", &tail.vars);
        }
        out.sort_by(|a, b| a.0.cmp(&b.0));
        out
    }
}

pub(super) struct Batch {
    pub(super) logits: Tensor,
    pub(super) features: Tensor,
    pub(super) targets: Tensor,
    pub(super) mask: Option<Tensor>,
}

impl Batch {
    pub(super) fn loss(&self) -> Result<Tensor> {
        Ok(match &self.mask {
            None => crate::loss::cross_entropy(&self.logits, &self.targets)?,
            Some(m) => crate::loss::masked_cross_entropy(&self.logits, &self.targets, m)?,
        })
    }

    /// (correct, counted) frames.
    pub(super) fn correct(&self) -> Result<(usize, usize)> {
        let pred: Vec<u32> = self.logits.argmax(D::Minus1)?.to_vec1()?;
        let tgt: Vec<u32> = self.targets.to_vec1()?;
        let mask: Vec<f32> = match &self.mask {
            Some(m) => m.to_vec1()?,
            None => vec![1.0; tgt.len()],
        };
        let mut c = (0, 0);
        for ((p, t), m) in pred.iter().zip(&tgt).zip(&mask) {
            if *m > 0.0 {
                c.1 += 1;
                c.0 += usize::from(p == t);
            }
        }
        Ok(c)
    }

    pub(super) fn frames(&self) -> Result<usize> {
        Ok(match &self.mask {
            Some(m) => m.sum_all()?.to_scalar::<f32>()? as usize,
            None => self.targets.dim(0)?,
        })
    }
}

/// `rows` from a start drawn uniformly among its first `fraction` of frames
/// (at least one frame is always kept; 0: all of `rows`, no draw).
fn cropped_start<'a>(rows: &'a [usize], fraction: f64, rng: &mut impl Rng) -> &'a [usize] {
    if fraction <= 0.0 || rows.len() < 2 {
        return rows;
    }
    let last_start = ((rows.len() as f64 * fraction).floor() as usize).min(rows.len() - 1);
    &rows[rng.gen_range(0..=last_start)..]
}

#[cfg(test)]
mod tests {
    use super::cropped_start;
    use rand::Rng;

    #[test]
    fn no_fraction_or_one_frame_keeps_the_sequence_and_draws_nothing() {
        let rows: Vec<usize> = (10..18).collect();
        let mut rng = crate::rng::stream(0, "crop");
        let mut untouched = rng.clone();
        assert_eq!(cropped_start(&rows, 0.0, &mut rng), &rows[..]);
        assert_eq!(cropped_start(&rows[..1], 1.0, &mut rng), &rows[..1]);
        assert_eq!(cropped_start(&[], 1.0, &mut rng), &[] as &[usize]);
        assert_eq!(rng.gen::<u64>(), untouched.gen::<u64>());
    }

    #[test]
    fn starts_cover_the_fraction_and_never_pass_it() {
        let rows: Vec<usize> = (0..10).collect();
        let mut rng = crate::rng::stream(1, "crop");
        let mut seen = [0usize; 10];
        for _ in 0..3000 {
            let kept = cropped_start(&rows, 0.5, &mut rng);
            assert_eq!(kept.last(), Some(&9), "the end of the reach is always kept");
            seen[kept[0]] += 1;
        }
        // floor(10 x 0.5) = 5: starts 0..=5, each about a sixth of the draws.
        for (start, n) in seen.iter().enumerate() {
            if start <= 5 {
                assert!((350..650).contains(n), "start {start} drawn {n} times");
            } else {
                assert_eq!(*n, 0, "start {start} is past the fraction");
            }
        }
    }

    #[test]
    fn a_whole_fraction_may_start_on_the_last_frame_but_keeps_one() {
        let rows = [4usize, 5, 6];
        let mut rng = crate::rng::stream(2, "crop");
        let mut shortest = usize::MAX;
        for _ in 0..200 {
            let kept = cropped_start(&rows, 1.0, &mut rng);
            assert!(!kept.is_empty());
            shortest = shortest.min(kept.len());
        }
        assert_eq!(shortest, 1);
    }
}
