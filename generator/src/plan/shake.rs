//! Handheld shake: the tremor and sway of a hand that carries a camera,
//! laid over the planned reach. Each of the camera's three rotation axes
//! and three position axes follows its own sum of sinusoids (frequencies
//! drawn in `frequency_hz`, random phases), scaled so that its RMS is the
//! configured amplitude. A closed form of time, so every frame's offset is
//! independent of the frame rate and of the other frames. Values come from
//! the sequence's own `shake` sub-stream: turning it on changes no other
//! value of the plan. Off by default; the camera test world turns it on.

use crate::config::error::{ConfigError, Result};
use grasp_schema::plan::{substream_seed, FramePlan};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use serde_json::json;

/// Sinusoids per axis: enough to look irregular, few enough to stay smooth.
const TERMS: usize = 3;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShakeConfig {
    pub enabled: bool,
    /// RMS rotation about each camera axis, degrees.
    pub rotation_deg: f64,
    /// RMS displacement along each world axis, metres.
    pub translation_m: f64,
    /// Range the sinusoids' frequencies are drawn in (log-uniform), Hz:
    /// physiological tremor lies at 4-12 Hz, arm sway below 2 Hz.
    pub frequency_hz: [f64; 2],
}

impl Default for ShakeConfig {
    fn default() -> Self {
        ShakeConfig {
            enabled: false,
            rotation_deg: 1.0,
            translation_m: 0.002,
            frequency_hz: [0.8, 8.0],
        }
    }
}

impl ShakeConfig {
    // Negated comparisons: a NaN must fail these checks.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn validate(&self) -> Result<()> {
        if !(self.rotation_deg >= 0.0 && self.rotation_deg <= 10.0) {
            return Err(ConfigError::rule(
                "plan.shake.rotation_deg",
                format!("must be in [0, 10] degrees, got {}", self.rotation_deg),
            ));
        }
        if !(self.translation_m >= 0.0 && self.translation_m <= 0.01) {
            return Err(ConfigError::rule(
                "plan.shake.translation_m",
                format!("must be in [0, 0.01] m, got {}", self.translation_m),
            ));
        }
        let [lo, hi] = self.frequency_hz;
        if !(lo > 0.0 && lo <= hi && hi <= 50.0) {
            return Err(ConfigError::rule(
                "plan.shake.frequency_hz",
                format!("must be 0 < low <= high <= 50 Hz, got [{lo}, {hi}]"),
            ));
        }
        Ok(())
    }
}

/// One axis's motion: amplitude, frequency (Hz) and phase per term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct Axis([(f64, f64, f64); TERMS]);

impl Axis {
    /// Terms drawn for an RMS of `rms`: each term's amplitude is
    /// `rms * sqrt(2 / TERMS)` times a weight, the weights' squares summing
    /// to `TERMS`, so the sum's RMS over long times is `rms`.
    fn draw(rng: &mut ChaCha8Rng, rms: f64, freq: [f64; 2]) -> Axis {
        let weights: [f64; TERMS] = std::array::from_fn(|_| rng.gen_range(0.5..1.5));
        let norm = (weights.iter().map(|w| w * w).sum::<f64>() / TERMS as f64).sqrt();
        let (ln_lo, ln_hi) = (freq[0].ln(), freq[1].ln());
        Axis(std::array::from_fn(|k| {
            let f = if ln_hi > ln_lo {
                rng.gen_range(ln_lo..ln_hi).exp()
            } else {
                freq[0]
            };
            let phase = rng.gen_range(0.0..std::f64::consts::TAU);
            let amp = rms * (2.0 / TERMS as f64).sqrt() * weights[k] / norm;
            (amp, f, phase)
        }))
    }

    fn at(&self, t: f64) -> f64 {
        self.0
            .iter()
            .map(|(a, f, p)| a * (std::f64::consts::TAU * f * t + p).sin())
            .sum()
    }
}

/// The shake of one sequence.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Shake {
    rotation: [Axis; 3],
    translation: [Axis; 3],
}

impl Shake {
    /// Draws the sequence's shake from its own sub-stream of `stream`.
    pub fn sample(cfg: &ShakeConfig, stream: u64) -> Shake {
        let mut rng = ChaCha8Rng::seed_from_u64(substream_seed(stream, "shake"));
        let rot = cfg.rotation_deg.to_radians();
        let rotation = std::array::from_fn(|_| Axis::draw(&mut rng, rot, cfg.frequency_hz));
        let translation =
            std::array::from_fn(|_| Axis::draw(&mut rng, cfg.translation_m, cfg.frequency_hz));
        Shake {
            rotation,
            translation,
        }
    }

    /// The rotation (about the camera's own axes, radians) and the world
    /// displacement (metres) at time `t`.
    pub fn offset(&self, t: f64) -> (Vector3<f64>, Vector3<f64>) {
        let r = Vector3::from_fn(|i, _| self.rotation[i].at(t));
        let d = Vector3::from_fn(|i, _| self.translation[i].at(t));
        (r, d)
    }

    /// Moves every frame's camera by the shake at its time: the rotation
    /// composed on the camera side (a turn of the hand), the displacement
    /// added in the world.
    pub fn apply(&self, frames: &mut [FramePlan]) {
        for f in frames {
            let (r, d) = self.offset(f.time_s);
            let [w, x, y, z] = f.camera.rotation_wxyz;
            let q = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
            let shaken = q * UnitQuaternion::from_scaled_axis(r);
            let c = shaken.into_inner().coords; // (x, y, z, w)
            f.camera.rotation_wxyz = [c.w, c.x, c.y, c.z];
            for (p, o) in f.camera.position.iter_mut().zip(d.iter()) {
                *p += o;
            }
        }
    }

    /// The record in the plan's `sampled` values.
    pub fn sampled(&self) -> serde_json::Value {
        json!(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grasp_schema::plan::Pose;
    use grasp_schema::Class;

    fn frames(n: usize, fps: f64) -> Vec<FramePlan> {
        (0..n)
            .map(|i| FramePlan {
                index: i as u32,
                time_s: i as f64 / fps,
                camera: Pose {
                    position: [0.1, 0.2, 0.3],
                    rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
                },
                class: Class::Power,
                head_camera: None,
            })
            .collect()
    }

    #[test]
    fn the_shake_has_its_rms_and_is_seeded() {
        let cfg = ShakeConfig {
            enabled: true,
            ..ShakeConfig::default()
        };
        let shake = Shake::sample(&cfg, 7);
        assert_eq!(shake, Shake::sample(&cfg, 7));
        assert_ne!(shake, Shake::sample(&cfg, 8));
        // Over 200 s at 1 kHz the RMS of every axis is within 15 % of the
        // configured amplitude (a few slow terms leave some spread).
        let n = 200_000;
        let mut sq = [0.0f64; 6];
        for i in 0..n {
            let (r, d) = shake.offset(i as f64 / 1000.0);
            for k in 0..3 {
                sq[k] += r[k] * r[k];
                sq[k + 3] += d[k] * d[k];
            }
        }
        let want = [cfg.rotation_deg.to_radians(), cfg.translation_m];
        for (k, s) in sq.iter().enumerate() {
            let rms = (s / n as f64).sqrt();
            let w = want[k / 3];
            assert!(
                (rms / w - 1.0).abs() < 0.15,
                "axis {k}: rms {rms} against {w}"
            );
        }
    }

    #[test]
    fn applied_it_turns_and_moves_each_frame_by_its_offset() {
        let cfg = ShakeConfig {
            enabled: true,
            rotation_deg: 2.0,
            translation_m: 0.003,
            ..ShakeConfig::default()
        };
        let shake = Shake::sample(&cfg, 1);
        let mut f = frames(10, 5.0);
        shake.apply(&mut f);
        for frame in &f {
            let (r, d) = shake.offset(frame.time_s);
            let [w, x, y, z] = frame.camera.rotation_wxyz;
            let norm = (w * w + x * x + y * y + z * z).sqrt();
            assert!((norm - 1.0).abs() < 1e-12, "a unit quaternion");
            // From identity, the rotation is the offset's: angle 2 acos(w).
            let angle = 2.0 * w.clamp(-1.0, 1.0).acos();
            assert!((angle - r.norm()).abs() < 1e-9);
            let moved = Vector3::from(frame.camera.position) - Vector3::new(0.1, 0.2, 0.3);
            assert!((moved - d).norm() < 1e-15);
        }
        // A zero amplitude leaves the frames as they were.
        let still = ShakeConfig {
            rotation_deg: 0.0,
            translation_m: 0.0,
            ..cfg
        };
        let mut g = frames(10, 5.0);
        Shake::sample(&still, 1).apply(&mut g);
        assert_eq!(g, frames(10, 5.0));
    }

    #[test]
    fn bad_settings_are_named() {
        for (cfg, field) in [
            (
                ShakeConfig {
                    rotation_deg: f64::NAN,
                    ..Default::default()
                },
                "rotation_deg",
            ),
            (
                ShakeConfig {
                    translation_m: 0.5,
                    ..Default::default()
                },
                "translation_m",
            ),
            (
                ShakeConfig {
                    frequency_hz: [5.0, 1.0],
                    ..Default::default()
                },
                "frequency_hz",
            ),
            (
                ShakeConfig {
                    frequency_hz: [0.0, 1.0],
                    ..Default::default()
                },
                "frequency_hz",
            ),
        ] {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
