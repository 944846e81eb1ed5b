//! When the wrist turns: the sampled onsets, durations and rates of the
//! two wrist rotations, in the authors' frame timing or a human-like one.

use crate::plan::scene::uniform;
use crate::plan::trajectory::{linear_window, min_jerk_window, WristTiming};
use crate::plan::TrajectoryConfig;
use rand_chacha::ChaCha8Rng;
use serde_json::json;

/// The sampled wrist-rotation timing, in normalised time.
pub struct WristSchedule {
    timing: WristTiming,
    approach_tau: f64,
    ps_onset_frame: f64,
    ps_duration_frames: f64,
    ps_fraction: f64,
    fe_onset_frame: f64,
    frames: f64,
    fe_rate: f64,
}

impl WristSchedule {
    pub fn sample(t: &TrajectoryConfig, approach_tau: f64, rng: &mut ChaCha8Rng) -> Self {
        // The authors round the frame draws to integers.
        WristSchedule {
            timing: t.wrist_timing,
            approach_tau,
            ps_onset_frame: uniform(rng, t.ps_onset_frames[0], t.ps_onset_frames[1]).round(),
            ps_duration_frames: uniform(rng, t.ps_duration_frames[0], t.ps_duration_frames[1])
                .round(),
            ps_fraction: uniform(rng, t.ps_fraction[0], t.ps_fraction[1]),
            fe_onset_frame: uniform(rng, t.fe_onset_frames[0], t.fe_onset_frames[1]).round(),
            frames: t.authors_frames,
            fe_rate: t.fe_rate_per_frame,
        }
    }

    /// Authors' frame -> normalised time of the approach phase.
    fn tau_of(&self, frame: f64) -> f64 {
        self.approach_tau + (frame / self.frames).min(1.0) * (1.0 - self.approach_tau)
    }

    fn approach_frames(&self, tau: f64) -> f64 {
        (tau - self.approach_tau) / (1.0 - self.approach_tau).max(1e-12) * self.frames
    }

    /// Executed fraction of the pronation-supination angle at `tau`.
    pub fn pronation_fraction(&self, tau: f64) -> f64 {
        let a = self.approach_tau;
        self.ps_fraction
            * match self.timing {
                WristTiming::Authors => {
                    let on = self.tau_of(self.ps_onset_frame);
                    let len = self.tau_of(self.ps_onset_frame + self.ps_duration_frames) - on;
                    linear_window(tau, on, len)
                }
                WristTiming::Human => min_jerk_window(tau, a, 1.0 - a),
            }
    }

    /// Executed fraction of the flexion-extension angle at `tau`.
    pub fn flexion_fraction(&self, tau: f64) -> f64 {
        let keep = 1.0 - self.fe_rate;
        let k = self.approach_frames(tau) - self.fe_onset_frame;
        match self.timing {
            WristTiming::Authors => {
                if k <= 0.0 {
                    0.0
                } else {
                    1.0 - keep.powf(k)
                }
            }
            WristTiming::Human => {
                let on = self.tau_of(self.fe_onset_frame);
                let left = (self.frames - self.fe_onset_frame).max(0.0);
                (1.0 - keep.powf(left)) * min_jerk_window(tau, on, 1.0 - on)
            }
        }
    }

    pub fn record(&self, put: &mut impl FnMut(&str, serde_json::Value)) {
        put(
            "wrist_timing",
            json!(format!("{:?}", self.timing).to_lowercase()),
        );
        put("ps_onset_frame", json!(self.ps_onset_frame));
        put("ps_duration_frames", json!(self.ps_duration_frames));
        put("ps_fraction", json!(self.ps_fraction));
        put("fe_onset_frame", json!(self.fe_onset_frame));
        put("fe_final_fraction", json!(self.flexion_fraction(1.0)));
    }
}
