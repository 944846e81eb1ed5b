//! Style views: a view whose frames go through the frozen backbone with
//! some blocks' channel statistics moved (grasp-model's
//! [`ChannelStyle`]). Section 14 of EXPERIMENTS.md measured it against a
//! held-out look. The draws come from the view's seed and the frame's
//! index, so a view's features are the same on every run and are cached
//! once.

use crate::error::ConfigError;
use grasp_model::style::ChannelStyle;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// One view's restyling: every frame gets its own draw.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StyleDraw {
    /// Standard deviation of the mean's shift (in spreads) and of the
    /// spread's log-scale.
    pub sigma: f32,
    /// The blocks whose outputs are restyled.
    pub blocks: Vec<usize>,
    pub seed: u64,
}

impl StyleDraw {
    /// The styles of frame `frame`, for a backbone whose blocks have
    /// `channels` output channels each.
    pub fn frame_styles(
        &self,
        frame: usize,
        channels: &[usize],
    ) -> Result<Vec<ChannelStyle>, ConfigError> {
        let mut rng = crate::rng::stream(self.seed, &format!("style/{frame}"));
        self.blocks
            .iter()
            .map(|&block| {
                let c = restylable(block, channels)?;
                let mut normal = || self.sigma * crate::rng::standard_normal(&mut rng);
                let shift = (0..c).map(|_| normal()).collect();
                let scale = (0..c).map(|_| normal().exp()).collect();
                Ok(ChannelStyle {
                    block,
                    shift,
                    scale,
                })
            })
            .collect()
    }
}

/// The channels of `block`, when the extractor whose restylable blocks
/// have `channels` can restyle it.
pub fn restylable(block: usize, channels: &[usize]) -> Result<usize, ConfigError> {
    channels.get(block).copied().ok_or_else(|| {
        ConfigError::invalid(
            "views.style_blocks",
            format!(
                "views.style_blocks: no block {block} to restyle; the frozen blocks in front of \
                 the features are 0 to {}",
                channels.len().saturating_sub(1)
            ),
        )
    })
}

/// A view's restyling, when `sigma` > 0.
pub fn draw(sigma: f32, blocks: &[usize], rng: &mut impl Rng) -> Option<StyleDraw> {
    (sigma > 0.0).then(|| StyleDraw {
        sigma,
        blocks: blocks.to_vec(),
        seed: rng.gen(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn style(sigma: f32) -> StyleDraw {
        StyleDraw {
            sigma,
            blocks: vec![1, 3],
            seed: 9,
        }
    }

    #[test]
    fn draws_are_seeded_per_frame_and_sized_per_block() {
        let channels = [16, 24, 24, 40];
        let s = style(0.3);
        let a = s.frame_styles(0, &channels).unwrap();
        assert_eq!(a, s.frame_styles(0, &channels).unwrap());
        assert_ne!(a, s.frame_styles(1, &channels).unwrap());
        assert_eq!(a.iter().map(|x| x.block).collect::<Vec<_>>(), [1, 3]);
        assert_eq!((a[0].shift.len(), a[1].scale.len()), (24, 40));
        let other_seed = StyleDraw { seed: 10, ..s };
        assert_ne!(a, other_seed.frame_styles(0, &channels).unwrap());
    }

    #[test]
    fn shifts_and_log_scales_have_the_configured_spread() {
        let s = StyleDraw {
            sigma: 0.3,
            blocks: vec![0],
            seed: 1,
        };
        let (mut shifts, mut logs) = (vec![], vec![]);
        for frame in 0..50 {
            let st = s.frame_styles(frame, &[200]).unwrap().remove(0);
            shifts.extend(st.shift.iter().map(|&x| f64::from(x)));
            logs.extend(st.scale.iter().map(|&x| f64::from(x).ln()));
        }
        for v in [shifts, logs] {
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
            // 10 000 draws: the mean within 4 standard errors, the spread within 3 %.
            assert!(mean.abs() < 4.0 * 0.3 / n.sqrt(), "{mean}");
            assert!((sd / 0.3 - 1.0).abs() < 0.03, "{sd}");
        }
    }

    #[test]
    fn no_style_at_sigma_zero_and_a_missing_block_is_named() {
        let mut rng = crate::rng::stream(1, "s");
        assert!(draw(0.0, &[2], &mut rng).is_none());
        let d = draw(0.2, &[2, 4], &mut rng).unwrap();
        assert_eq!((d.sigma, d.blocks.as_slice()), (0.2, &[2, 4][..]));
        let err = d.frame_styles(0, &[8, 8, 8]).unwrap_err().to_string();
        assert!(
            err.contains("views.style_blocks") && err.contains("block 4"),
            "{err}"
        );
    }
}
