//! View damping: the frozen features made less sensitive to what the
//! training views change. A view shows the same frame in another look
//! (style views) or through another crop, so whatever moves between a frame
//! and its views is not the grasp. The principal directions of those
//! changes (their uncentred covariance `C`) are scaled down in the
//! features, `x -> (I + damping C / mean eigenvalue)^(-1/2) x`, so the head
//! needs large weights, which its L2 penalty resists, to read them. The
//! map is linear and folded into the head's input weights when the
//! checkpoint is written, so a checkpoint reads the backbone's features as
//! any other does and the runtime needs nothing new.

use super::{FrameSource, SplitFrames};
use crate::error::{Result, TrainError};
use candle_core::{DType, Tensor};

/// The damping map `x -> x - ((x B) * removed) B^T`.
#[derive(Debug, Clone)]
pub struct ViewDamping {
    /// (dim, dim): the change covariance's eigenvectors, one per column.
    basis: Tensor,
    /// (1, dim): the share of each direction taken away, in [0, 1).
    removed: Tensor,
    /// The largest direction's share of the views' changes.
    pub leading_share: f64,
}

impl ViewDamping {
    /// The damping of `strength` for the differences between each view's
    /// frames and the same frames of its original sequence. The originals
    /// are the first `originals` sequences of `frames`, each view a copy of
    /// them in the same order (see `with_views`). None when there are no
    /// views or they change nothing.
    pub fn from_views(
        frames: &SplitFrames,
        originals: usize,
        strength: f64,
    ) -> Result<Option<Self>> {
        let FrameSource::Cached(x) = &frames.source else {
            let why = "view damping needs cached features (frozen mode)";
            return Err(TrainError::Inconsistent(why));
        };
        Self::from_changes(x, &frames.seq_rows, originals, strength).map_err(|source| {
            TrainError::Tensors {
                context: "computing the views' feature changes",
                source,
            }
        })
    }

    /// [`Self::from_views`] of the cached features `x`.
    fn from_changes(
        x: &Tensor,
        seq_rows: &[Vec<usize>],
        originals: usize,
        strength: f64,
    ) -> candle_core::Result<Option<Self>> {
        let Some(diff) = view_changes(x, seq_rows, originals)? else {
            return Ok(None);
        };
        // Uncentred: a shift that every view shares is a change too. f64 for
        // the sum over tens of thousands of rows.
        let diff = diff.to_dtype(DType::F64)?;
        let cov = diff.t()?.matmul(&diff)?;
        let dim = cov.dim(0)?;
        let flat: Vec<f64> = cov.flatten_all()?.to_vec1()?;
        // faer's blocked, parallel solver: 10 s less than nalgebra's at
        // Lite0's 1984 features (BENCHMARKS.md, "View damping's
        // eigendecomposition").
        let cov = faer::MatRef::from_row_major_slice(&flat, dim, dim);
        let eig = cov.self_adjoint_eigen(faer::Side::Lower).map_err(|e| {
            candle_core::Error::Msg(format!("view damping: eigendecomposition: {e:?}"))
        })?;
        let variances: Vec<f64> = (0..dim).map(|i| eig.S()[i].max(0.0)).collect();
        let total: f64 = variances.iter().sum();
        if total <= 0.0 || !total.is_finite() {
            return Ok(None);
        }
        let mean = total / dim as f64;
        let removed: Vec<f32> = variances
            .iter()
            .map(|v| (1.0 - 1.0 / (1.0 + strength * v / mean).sqrt()) as f32)
            .collect();
        // Row r holds coordinate r of every eigenvector (one per column).
        let u = eig.U();
        let basis: Vec<f32> = (0..dim)
            .flat_map(|r| (0..dim).map(move |c| u[(r, c)] as f32))
            .collect();
        let dev = x.device();
        Ok(Some(ViewDamping {
            basis: Tensor::from_vec(basis, (dim, dim), dev)?,
            removed: Tensor::from_vec(removed, (1, dim), dev)?,
            leading_share: variances.iter().cloned().fold(0.0, f64::max) / total,
        }))
    }

    /// `m`'s rows (.., dim) damped.
    pub fn apply(&self, m: &Tensor) -> candle_core::Result<Tensor> {
        let along = m.matmul(&self.basis)?.broadcast_mul(&self.removed)?;
        m - along.matmul(&self.basis.t()?)?
    }

    /// `m`'s rows damped block by block, for weights that read several
    /// copies of the features side by side (the trace head's `[f, m]`: the
    /// trace of damped features is the damped trace, the map being linear).
    fn apply_blocks(&self, m: &Tensor) -> candle_core::Result<Tensor> {
        let dim = self.basis.dim(0)?;
        let width = m.dim(1)?;
        if width == dim || width % dim != 0 {
            return self.apply(m);
        }
        let blocks = (0..width / dim)
            .map(|b| self.apply(&m.narrow(1, b * dim, dim)?))
            .collect::<candle_core::Result<Vec<_>>>()?;
        Tensor::cat(&blocks, 1)
    }

    /// `frames`' cached features, damped.
    pub fn apply_to_frames(&self, frames: &mut SplitFrames) -> Result<()> {
        if let FrameSource::Cached(x) = &frames.source {
            let damped = self.apply(x).map_err(|source| TrainError::Tensors {
                context: "damping features",
                source,
            })?;
            frames.source = FrameSource::Cached(damped);
        }
        Ok(())
    }

    /// The checkpoint's tensors with the damping folded into the weights
    /// that read the features (`input`: `head.fc.weight` of an FC head,
    /// `head.lstm.weight_ih_l0` of an LSTM): the map is symmetric, so
    /// `W (D x) = (W D) x` with `W D` = `W`'s rows damped.
    pub fn fold(
        &self,
        tensors: Vec<(String, Tensor)>,
        input: &str,
    ) -> candle_core::Result<Vec<(String, Tensor)>> {
        tensors
            .into_iter()
            .map(|(name, t)| {
                let t = if name == input {
                    self.apply_blocks(&t)?
                } else {
                    t
                };
                Ok((name, t))
            })
            .collect()
    }
}

/// Every view frame's features minus its original's, one row each; None
/// without views.
fn view_changes(
    x: &Tensor,
    seq_rows: &[Vec<usize>],
    originals: usize,
) -> candle_core::Result<Option<Tensor>> {
    let (mut from, mut to) = (Vec::new(), Vec::new());
    if originals > 0 {
        for (i, rows) in seq_rows.iter().enumerate().skip(originals) {
            let base = &seq_rows[i % originals];
            // A frame unreadable in one and not the other leaves the pairing unknown.
            if rows.len() == base.len() {
                from.extend(base.iter().map(|&r| r as u32));
                to.extend(rows.iter().map(|&r| r as u32));
            }
        }
    }
    if from.is_empty() {
        return Ok(None);
    }
    let pick = |rows: Vec<u32>| -> candle_core::Result<Tensor> {
        let n = rows.len();
        x.index_select(&Tensor::from_vec(rows, n, x.device())?, 0)
    };
    Ok(Some((pick(to)? - pick(from)?)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    /// Two originals of three frames in 4-d features and one view of each
    /// that moves every frame along `along` by a different amount.
    fn frames(along: [f32; 4]) -> SplitFrames {
        let base = |r: usize| [r as f32, (r * r) as f32 * 0.1, 1.0 - r as f32, 0.5];
        let mut x = Vec::new();
        for r in 0..6 {
            x.extend(base(r));
        }
        for r in 0..6 {
            let a = (r as f32 - 2.5) * 0.7;
            x.extend(base(r).iter().zip(along).map(|(b, d)| b + a * d));
        }
        SplitFrames {
            labels: vec![0; 12],
            seq_rows: vec![vec![0, 1, 2], vec![3, 4, 5], vec![6, 7, 8], vec![9, 10, 11]],
            seq_times: vec![vec![0.0, 0.4, 0.8]; 4],
            seq_class: vec![0; 4],
            seq_ids: (0..4).map(|i| format!("s{i}")).collect(),
            source: FrameSource::Cached(Tensor::from_vec(x, (12, 4), &Device::Cpu).unwrap()),
        }
    }

    fn rows(t: &Tensor) -> Vec<Vec<f32>> {
        t.to_vec2().unwrap()
    }

    fn dot(a: &[f32], b: &[f32]) -> f32 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    #[test]
    fn the_views_direction_is_damped_and_the_rest_kept() {
        // One direction holds all the change: its variance is 4 times the
        // mean of the 4 eigenvalues, so strength 2 scales it by 1 / 3.
        let along = [0.6, 0.0, 0.8, 0.0];
        let f = frames(along);
        let d = ViewDamping::from_views(&f, 2, 2.0).unwrap().unwrap();
        assert!((d.leading_share - 1.0).abs() < 1e-9, "{}", d.leading_share);
        let x = Tensor::new(
            &[[0.6f32, 0.0, 0.8, 0.0], [0.8, 1.0, -0.6, 2.0]],
            &Device::Cpu,
        )
        .unwrap();
        let out = rows(&d.apply(&x).unwrap());
        for (c, want) in out[0].iter().zip(along) {
            assert!((c - want / 3.0).abs() < 1e-5, "{:?}", out[0]);
        }
        // Orthogonal to the change: untouched.
        for (c, want) in out[1].iter().zip([0.8, 1.0, -0.6, 2.0]) {
            assert!((c - want).abs() < 1e-5, "{:?}", out[1]);
        }
    }

    #[test]
    fn damping_shrinks_the_gap_between_a_view_and_its_frame() {
        let mut f = frames([0.0, 0.6, 0.0, 0.8]);
        let before = rows(match &f.source {
            FrameSource::Cached(x) => x,
            FrameSource::Images(_) => unreachable!(),
        });
        let d = ViewDamping::from_views(&f, 2, 8.75).unwrap().unwrap();
        d.apply_to_frames(&mut f).unwrap();
        let FrameSource::Cached(x) = &f.source else {
            unreachable!()
        };
        let after = rows(x);
        let gap = |m: &[Vec<f32>], r: usize| {
            let g: Vec<f32> = m[r].iter().zip(&m[r + 6]).map(|(a, b)| a - b).collect();
            dot(&g, &g).sqrt()
        };
        // Strength 8.75 on 4 x the mean variance: 1 / sqrt(36) of the change.
        assert!((gap(&after, 0) * 6.0 - gap(&before, 0)).abs() < 1e-4);
    }

    #[test]
    fn folding_into_the_weights_gives_the_damped_features_logits() {
        let d = ViewDamping::from_views(&frames([0.0, 1.0, 0.0, 0.0]), 2, 3.0)
            .unwrap()
            .unwrap();
        let w = Tensor::new(
            &[[1.0f32, 2.0, 3.0, 4.0], [-1.0, 0.5, 0.0, 2.0]],
            &Device::Cpu,
        )
        .unwrap();
        let x = Tensor::new(&[[0.3f32, -1.0, 2.0, 0.7]], &Device::Cpu).unwrap();
        let folded = d
            .fold(
                vec![
                    ("head.fc.bias".into(), w.clone()),
                    ("head.fc.weight".into(), w.clone()),
                ],
                "head.fc.weight",
            )
            .unwrap();
        assert_eq!(
            rows(&folded[0].1),
            rows(&w),
            "only the input weights change"
        );
        let want = d.apply(&x).unwrap().matmul(&w.t().unwrap()).unwrap();
        let got = x.matmul(&folded[1].1.t().unwrap()).unwrap();
        for (a, b) in rows(&want)[0].iter().zip(&rows(&got)[0]) {
            assert!((a - b).abs() < 1e-5, "{a} {b}");
        }
    }

    #[test]
    fn no_views_or_views_that_change_nothing_give_no_damping() {
        let mut f = frames([0.0; 4]);
        assert!(ViewDamping::from_views(&f, 2, 1.0).unwrap().is_none());
        f.seq_rows.truncate(2);
        assert!(ViewDamping::from_views(&f, 2, 1.0).unwrap().is_none());
        assert!(ViewDamping::from_views(&f, 0, 1.0).unwrap().is_none());
    }
}
