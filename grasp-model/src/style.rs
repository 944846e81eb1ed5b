//! Restyling a block's output: feature-statistics augmentation for the
//! frozen backbone. A convolution's per-channel mean and spread over the
//! image carry much of a picture's look (colour cast, contrast, texture
//! energy, noise) and little of its layout. Moving them, and letting the
//! rest of the network run on, shows the head the same scene in a look the
//! renderer never drew.

use candle_core::{Result, Tensor};

/// Keeps the spread of a flat channel away from zero.
const SPREAD_EPS: f64 = 1e-6;

/// A new look for the output of one block: each channel's mean moves by
/// `shift` times the channel's spread over the image, and its deviations
/// from that mean are multiplied by `scale`.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelStyle {
    /// The block whose output is restyled.
    pub block: usize,
    /// One per channel, in spreads.
    pub shift: Vec<f32>,
    /// One per channel, positive.
    pub scale: Vec<f32>,
}

impl ChannelStyle {
    /// `y` (N, C, H, W) with every image's channel statistics moved.
    pub fn apply(&self, y: &Tensor) -> Result<Tensor> {
        let (_, c, _, _) = y.dims4()?;
        if self.shift.len() != c || self.scale.len() != c {
            candle_core::bail!(
                "block {}'s style has {} shifts and {} scales for {c} channels",
                self.block,
                self.shift.len(),
                self.scale.len()
            );
        }
        let per_channel = |v: &[f32]| Tensor::from_slice(v, (1, c, 1, 1), y.device());
        let mean = y.mean_keepdim(3)?.mean_keepdim(2)?;
        let deviation = y.broadcast_sub(&mean)?;
        let spread = (deviation.sqr()?.mean_keepdim(3)?.mean_keepdim(2)? + SPREAD_EPS)?.sqrt()?;
        let new_mean = (&mean + spread.broadcast_mul(&per_channel(&self.shift)?)?)?;
        deviation
            .broadcast_mul(&per_channel(&self.scale)?)?
            .broadcast_add(&new_mean)
    }
}

/// `y` restyled by every style in `styles` meant for `block`.
pub fn restyle(y: Tensor, block: usize, styles: &[ChannelStyle]) -> Result<Tensor> {
    styles
        .iter()
        .filter(|s| s.block == block)
        .try_fold(y, |y, s| s.apply(&y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, D};

    fn stats(t: &Tensor) -> (Vec<f32>, Vec<f32>) {
        let flat = t.flatten_from(2).unwrap();
        let mean = flat.mean(D::Minus1).unwrap();
        let dev = flat.broadcast_sub(&mean.unsqueeze(2).unwrap()).unwrap();
        let var = dev.sqr().unwrap().mean(D::Minus1).unwrap();
        (
            mean.flatten_all().unwrap().to_vec1().unwrap(),
            var.sqrt()
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1()
                .unwrap(),
        )
    }

    fn map() -> Tensor {
        // Two images, two channels of 3 x 3, each channel its own mean and spread.
        let v: Vec<f32> = (0..36)
            .map(|i| ((i * 7) % 11) as f32 * (1.0 + (i / 9) as f32) - 3.0)
            .collect();
        Tensor::from_vec(v, (2, 2, 3, 3), &Device::Cpu).unwrap()
    }

    #[test]
    fn moves_each_channels_mean_and_spread_by_its_own_spread() {
        let y = map();
        let style = ChannelStyle {
            block: 3,
            shift: vec![0.5, -1.0],
            scale: vec![2.0, 0.25],
        };
        let (m0, s0) = stats(&y);
        let (m1, s1) = stats(&style.apply(&y).unwrap());
        for i in 0..4 {
            let c = i % 2;
            let want_mean = m0[i] + style.shift[c] * s0[i];
            assert!(
                (m1[i] - want_mean).abs() < 1e-4,
                "{i}: {} {want_mean}",
                m1[i]
            );
            assert!((s1[i] - style.scale[c] * s0[i]).abs() < 1e-4, "{i}");
        }
    }

    #[test]
    fn the_identity_style_and_other_blocks_leave_the_map_alone() {
        let y = map();
        let identity = ChannelStyle {
            block: 3,
            shift: vec![0.0; 2],
            scale: vec![1.0; 2],
        };
        let same = identity.apply(&y).unwrap();
        assert!(crate::test_util::max_diff(&y, &same) < 1e-5);
        let elsewhere = ChannelStyle {
            block: 4,
            shift: vec![3.0; 2],
            scale: vec![3.0; 2],
        };
        let out = restyle(y.clone(), 3, &[elsewhere]).unwrap();
        assert_eq!(crate::test_util::max_diff(&y, &out), 0.0);
    }

    #[test]
    fn a_flat_channel_stays_finite_and_a_wrong_width_is_refused() {
        let flat = Tensor::zeros((1, 2, 4, 4), candle_core::DType::F32, &Device::Cpu).unwrap();
        let style = ChannelStyle {
            block: 0,
            shift: vec![1.0, -1.0],
            scale: vec![5.0, 0.1],
        };
        let out = style.apply(&flat).unwrap();
        let v: Vec<f32> = out.flatten_all().unwrap().to_vec1().unwrap();
        assert!(v.iter().all(|x| x.is_finite() && x.abs() < 1e-2));
        let narrow = ChannelStyle {
            shift: vec![0.0],
            ..style
        };
        let err = narrow.apply(&flat).unwrap_err().to_string();
        assert!(
            err.contains("1 shifts") && err.contains("2 channels"),
            "{err}"
        );
    }
}
