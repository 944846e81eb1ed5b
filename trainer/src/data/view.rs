//! Augmented views for the frozen-backbone mode. The backbone's features are
//! computed once and cached, so the from-scratch augmentation (a new draw
//! every epoch) does not apply. Instead each training sequence gets `count`
//! extra copies, each seen through a fixed, seeded variation of the centre
//! crop: its size scaled, its centre shifted, its colours jittered and,
//! when `noise` or `blur_px` is set, a noisier or softer sensor
//! ([`SensorProbe`]). A view is one draw per
//! sequence, the same for all its frames, as a slightly different lens,
//! aim, white balance and sensor would be. With `style` set, a view also
//! restyles some of the backbone's block outputs, a new draw every frame
//! ([`super::style`]).

use super::augment::jitter;
use super::probe::{SensorProbe, MAX_BLUR_PX, MAX_NOISE_SIGMA};
use super::Dataset;
use crate::error::ConfigError;
use image::{imageops, RgbImage};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// How many views, and how far they stray from the plain centre crop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViewConfig {
    /// Extra views per training sequence (0: the frames as they are).
    pub count: usize,
    /// The crop side is scaled by a factor in [1 / (1 + scale), 1 + scale],
    /// drawn log-uniformly.
    pub scale: f64,
    /// The crop centre moves by up to this fraction of the crop side, along
    /// each axis.
    pub shift: f64,
    /// Brightness, contrast and saturation factors in [1 - color, 1 + color].
    pub color: f32,
    /// Extra sensor noise added to every frame of a view: its sigma (a
    /// fraction of full scale) is drawn uniformly from this range, on top of
    /// the noise the frames were rendered with. [0, 0]: none.
    pub noise: [f32; 2],
    /// Gaussian defocus blur before that noise, pixels of the frame, drawn
    /// uniformly from this range. [0, 0]: none.
    pub blur_px: [f32; 2],
    /// Style views: the outputs of `style_blocks` get each channel's mean
    /// moved by N(0, style) of its spread and its spread scaled by
    /// exp(N(0, style)), drawn per frame. 0: off.
    pub style: f32,
    /// The blocks restyled (EfficientNet-Lite's block indices; the default
    /// ends Lite0's stages 1, 2 and 3).
    pub style_blocks: Vec<usize>,
}

/// Style views' blocks by default: the ends of Lite0's 24-, 40- and
/// 80-channel stages, where the look is still separate from the layout.
pub const DEFAULT_STYLE_BLOCKS: [usize; 3] = [2, 4, 7];

/// Style strengths accepted: at 1 a channel's spread varies by e either way.
pub const MAX_STYLE: f32 = 1.0;

impl Default for ViewConfig {
    fn default() -> Self {
        ViewConfig {
            count: 0,
            scale: 0.25,
            shift: 0.15,
            color: 0.2,
            noise: [0.0, 0.0],
            blur_px: [0.0, 0.0],
            style: 0.0,
            style_blocks: DEFAULT_STYLE_BLOCKS.to_vec(),
        }
    }
}

impl ViewConfig {
    /// Refuses ranges a view cannot be drawn from, naming the field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let range_ok = |[lo, hi]: [f32; 2], max: f32| {
            lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi && hi <= max
        };
        let checks = [
            (
                self.scale.is_finite() && (0.0..=1.0).contains(&self.scale),
                "views.scale",
                format!("views.scale must be in [0, 1], got {}", self.scale),
            ),
            (
                self.shift.is_finite() && (0.0..=0.5).contains(&self.shift),
                "views.shift",
                format!("views.shift must be in [0, 0.5], got {}", self.shift),
            ),
            (
                self.color.is_finite() && (0.0..1.0).contains(&self.color),
                "views.color",
                format!("views.color must be in [0, 1), got {}", self.color),
            ),
            (
                range_ok(self.noise, MAX_NOISE_SIGMA),
                "views.noise",
                format!(
                    "views.noise must be a range [low, high] within [0, 1] (a fraction of full scale), got {:?}",
                    self.noise
                ),
            ),
            (
                range_ok(self.blur_px, MAX_BLUR_PX),
                "views.blur_px",
                format!(
                    "views.blur_px must be a range [low, high] within [0, 50] pixels, got {:?}",
                    self.blur_px
                ),
            ),
            (
                self.style.is_finite() && (0.0..=MAX_STYLE).contains(&self.style),
                "views.style",
                format!("views.style must be in [0, {MAX_STYLE}], got {}", self.style),
            ),
            (
                self.style == 0.0 || !self.style_blocks.is_empty(),
                "views.style_blocks",
                format!(
                    "views.style is {} but views.style_blocks is empty: name the blocks to restyle",
                    self.style
                ),
            ),
        ];
        match checks.into_iter().find(|(ok, _, _)| !ok) {
            Some((_, field, reason)) => Err(ConfigError::invalid(field, reason)),
            None => Ok(()),
        }
    }
}

/// One view's draws: applied to every frame of its sequence.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewJitter {
    /// Multiplies the crop side.
    pub scale: f64,
    /// Moves the crop centre, in crop sides.
    pub shift: [f64; 2],
    pub brightness: f32,
    pub contrast: f32,
    pub saturation: f32,
}

impl ViewJitter {
    pub fn draw(cfg: &ViewConfig, rng: &mut impl Rng) -> ViewJitter {
        let log_scale = (1.0 + cfg.scale).ln();
        let mut within = |a: f64| if a > 0.0 { rng.gen_range(-a..=a) } else { 0.0 };
        let scale = within(log_scale).exp();
        let shift = [within(cfg.shift), within(cfg.shift)];
        let c = f64::from(cfg.color);
        let mut factor = || 1.0 + within(c) as f32;
        ViewJitter {
            scale,
            shift,
            brightness: factor(),
            contrast: factor(),
            saturation: factor(),
        }
    }

    /// `img` through this view: the square the centre crop `crop` (a
    /// fraction of the shorter side; None: all of it) would take, scaled and
    /// shifted, then colour-jittered. The square stays inside the image and
    /// inside the centred `region` that was rendered (`[render]
    /// center_region`; None: all of it), so a view never shows the black
    /// border of a frame rendered only in its centre.
    pub fn apply(&self, img: &RgbImage, crop: Option<f64>, region: Option<f64>) -> RgbImage {
        let (w, h) = img.dimensions();
        let short = f64::from(w.min(h));
        let bound = (short * region.unwrap_or(1.0)).round().clamp(1.0, short);
        let side = (short * crop.unwrap_or(1.0) * self.scale)
            .round()
            .clamp(1.0, bound);
        let place = |extent: u32, shift: f64| {
            let middle = f64::from(extent) / 2.0;
            let start = middle + shift * side - side / 2.0;
            let lowest = (middle - bound / 2.0).round().max(0.0);
            let highest = (lowest + bound - side).min(f64::from(extent) - side);
            start.round().clamp(lowest, highest) as u32
        };
        let (x, y) = (place(w, self.shift[0]), place(h, -self.shift[1]));
        let s = side as u32;
        let mut out = imageops::crop_imm(img, x, y, s, s).to_image();
        jitter(&mut out, self.brightness, self.contrast, self.saturation);
        out
    }
}

/// `data` followed by `cfg.count` views of each of its sequences, drawn
/// from `seed` and the sequence id (the same views on every run with that
/// seed, so their features are cached once).
pub fn with_views(data: &Dataset, cfg: &ViewConfig, seed: u64) -> Dataset {
    let mut sequences = data.sequences.clone();
    for k in 1..=cfg.count {
        for seq in &data.sequences {
            let mut rng = crate::rng::stream(seed, &format!("view/{k}/{}", seq.id));
            let mut v = seq.clone();
            v.id = format!("{}#view{k}", seq.id);
            v.view = Some(ViewJitter::draw(cfg, &mut rng));
            v.probe = draw_sensor(cfg, &mut rng);
            v.style = super::style::draw(cfg.style, &cfg.style_blocks, &mut rng);
            sequences.push(v);
        }
    }
    Dataset {
        root: data.root.clone(),
        sequences,
    }
}

/// A view's sensor: noise and defocus drawn from the config's ranges (None
/// when both ranges are [0, 0]). Drawn after the [`ViewJitter`], so adding
/// a sensor range leaves the views' crops and colours as they were.
fn draw_sensor(cfg: &ViewConfig, rng: &mut impl Rng) -> Option<SensorProbe> {
    let mut within = |[lo, hi]: [f32; 2]| if hi > lo { rng.gen_range(lo..=hi) } else { lo };
    SensorProbe {
        noise_sigma: within(cfg.noise),
        blur_sigma_px: within(cfg.blur_px),
    }
    .active()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plain() -> ViewJitter {
        ViewJitter {
            scale: 1.0,
            shift: [0.0, 0.0],
            brightness: 1.0,
            contrast: 1.0,
            saturation: 1.0,
        }
    }

    fn ramp(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, 0]))
    }

    #[test]
    fn the_plain_view_is_the_centre_crop() {
        let img = ramp(100, 80);
        let out = plain().apply(&img, Some(0.5), None);
        assert_eq!(out, crate::data::images::center_crop(&img, 0.5));
        assert_eq!(plain().apply(&img, None, None).dimensions(), (80, 80));
    }

    #[test]
    fn scale_and_shift_move_the_crop_and_stay_inside() {
        let img = ramp(100, 100);
        let v = ViewJitter {
            scale: 1.2,
            shift: [0.1, 0.1],
            ..plain()
        };
        let out = v.apply(&img, Some(0.5), None);
        assert_eq!(out.dimensions(), (60, 60));
        // Centre 50 + 6 right and 6 up: the crop starts at x 26, y 14.
        assert_eq!(out.get_pixel(0, 0), &image::Rgb([26, 14, 0]));
        let far = ViewJitter {
            scale: 3.0,
            shift: [0.5, -0.5],
            ..plain()
        };
        let out = far.apply(&img, Some(0.5), None);
        assert_eq!(out.dimensions(), (100, 100), "clamped to the image");
        let tiny = ViewJitter {
            scale: 1e-9,
            ..plain()
        };
        assert_eq!(tiny.apply(&img, Some(0.5), None).dimensions(), (1, 1));
    }

    #[test]
    fn views_stay_inside_the_rendered_region() {
        // A 100 px frame rendered only in its central 50 px (25..75).
        let img = ramp(100, 100);
        let wide = ViewJitter {
            scale: 1.25,
            ..plain()
        };
        // Crop 0.42 x 1.25 would be 53 px, past the 50 px region.
        let out = wide.apply(&img, Some(0.42), Some(0.5));
        assert_eq!(out.dimensions(), (50, 50));
        assert_eq!(out.get_pixel(0, 0), &image::Rgb([25, 25, 0]));
        // Shifted: it slides back to the region's edge, not the image's.
        let shifted = ViewJitter {
            shift: [0.5, 0.5],
            ..plain()
        };
        let out = shifted.apply(&img, Some(0.42), Some(0.5));
        assert_eq!(out.dimensions(), (42, 42));
        assert_eq!(out.get_pixel(0, 0), &image::Rgb([33, 25, 0]));
        // Inside the region nothing changes.
        assert_eq!(
            plain().apply(&img, Some(0.42), Some(0.5)),
            plain().apply(&img, Some(0.42), None)
        );
    }

    #[test]
    fn views_are_seeded_and_within_range() {
        let cfg = ViewConfig {
            count: 2,
            ..Default::default()
        };
        let mut a = crate::rng::stream(7, "v");
        let mut b = crate::rng::stream(7, "v");
        for _ in 0..200 {
            let v = ViewJitter::draw(&cfg, &mut a);
            assert_eq!(v, ViewJitter::draw(&cfg, &mut b));
            assert!(v.scale >= 1.0 / 1.25 - 1e-12 && v.scale <= 1.25 + 1e-12);
            assert!(v.shift.iter().all(|s| s.abs() <= 0.15));
            assert!((0.8..=1.2).contains(&v.brightness));
        }
        let none = ViewConfig {
            scale: 0.0,
            shift: 0.0,
            color: 0.0,
            ..cfg.clone()
        };
        assert_eq!(ViewJitter::draw(&none, &mut a), plain());
        assert!(ViewConfig {
            scale: 2.0,
            ..cfg.clone()
        }
        .validate()
        .is_err());
        assert!(ViewConfig {
            color: f32::NAN,
            ..cfg.clone()
        }
        .validate()
        .is_err());
        assert!(cfg.validate().is_ok());
    }

    fn one_sequence(id: &str) -> crate::data::Sequence {
        crate::data::Sequence {
            id: id.into(),
            dir: Default::default(),
            category: "c".into(),
            object: "o".into(),
            part: Some("p".into()),
            preshape: grasp_schema::taxonomy::Preshape::Power,
            condition: "default".into(),
            fps: 30.0,
            frames: vec!["a.png".into(), "b.png".into()],
            labels: vec![grasp_schema::taxonomy::Class::NoGrasp; 2],
            label_source: crate::data::LabelSource::SequenceJson,
            crop: grasp_model::input::Crop::Fraction(0.5),
            lens: None,
            lead_in: 0,
            first_frame: 0,
            rendered_region: None,
            denoise: false,
            test_world: None,
            view: None,
            probe: None,
            style: None,
        }
    }

    #[test]
    fn with_views_appends_labelled_copies() {
        let seq = one_sequence;
        let data = Dataset {
            root: Default::default(),
            sequences: vec![seq("s0"), seq("s1"), seq("s2")],
        };
        let n = data.sequences.len();
        let cfg = ViewConfig {
            count: 2,
            ..Default::default()
        };
        let out = with_views(&data, &cfg, 1);
        assert_eq!(out.sequences.len(), 3 * n);
        assert!(out.sequences[..n].iter().all(|s| s.view.is_none()));
        for (i, v) in out.sequences[n..].iter().enumerate() {
            let src = &data.sequences[i % n];
            assert_eq!(v.labels, src.labels);
            assert_eq!(v.frames, src.frames);
            assert!(v.view.is_some() && v.id.starts_with(&src.id));
        }
        assert_ne!(out.sequences[n].view, out.sequences[2 * n].view);
        assert_eq!(with_views(&data, &cfg, 1).sequences, out.sequences);
    }

    #[test]
    fn sensor_views_draw_noise_and_blur_within_their_ranges() {
        let data = Dataset {
            root: Default::default(),
            sequences: (0..40).map(|i| one_sequence(&format!("s{i}"))).collect(),
        };
        let plain_cfg = ViewConfig {
            count: 2,
            ..Default::default()
        };
        let plain_views = with_views(&data, &plain_cfg, 3);
        assert!(plain_views.sequences.iter().all(|s| s.probe.is_none()));
        let cfg = ViewConfig {
            noise: [0.01, 0.02],
            blur_px: [0.0, 0.5],
            ..plain_cfg
        };
        let sensed = with_views(&data, &cfg, 3);
        let n = data.sequences.len();
        assert!(sensed.sequences[..n].iter().all(|s| s.probe.is_none()));
        let probes: Vec<SensorProbe> = sensed.sequences[n..]
            .iter()
            .map(|s| s.probe.expect("every view has a sensor"))
            .collect();
        assert!(probes
            .iter()
            .all(|p| (0.01..=0.02).contains(&p.noise_sigma)
                && (0.0..=0.5).contains(&p.blur_sigma_px)));
        assert!(
            probes.iter().any(|p| p.noise_sigma < 0.013)
                && probes.iter().any(|p| p.noise_sigma > 0.017)
        );
        assert!(
            probes.iter().any(|p| p.blur_sigma_px < 0.1)
                && probes.iter().any(|p| p.blur_sigma_px > 0.4)
        );
        // The sensor is drawn after the crop: the crops stay as they were.
        for (a, b) in sensed.sequences.iter().zip(&plain_views.sequences) {
            assert_eq!(a.view, b.view);
        }
        for bad in [[0.02, 0.01], [-0.1, 0.0], [0.0, f32::NAN], [0.0, 2.0]] {
            assert!(
                ViewConfig {
                    noise: bad,
                    ..cfg.clone()
                }
                .validate()
                .is_err(),
                "{bad:?}"
            );
        }
        assert!(ViewConfig {
            blur_px: [0.0, 60.0],
            ..cfg.clone()
        }
        .validate()
        .is_err());
        assert!(cfg.validate().is_ok());
    }
}
