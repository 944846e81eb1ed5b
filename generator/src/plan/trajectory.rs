//! Camera paths with the minimum-jerk time law (Flash & Hogan 1985).
//!
//! Every position is evaluated in closed form from the normalised time
//! `tau` in [0, 1]; nothing is accumulated frame by frame, so the endpoint is
//! exact for any frame count.

use crate::config::error::{ConfigError, Result};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// When the wrist rotations happen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WristTiming {
    /// The authors' script: pronation-supination at a constant rate over a
    /// sampled window, flexion-extension converging by a fixed fraction per
    /// (authors') frame from a sampled onset.
    Authors,
    /// More human: pronation-supination follows the same minimum-jerk law
    /// as the reach from movement onset; flexion-extension follows a
    /// minimum-jerk ramp from its onset to the end, to the same final angle.
    Human,
}

/// Timing, labels and wrist-rotation ranges of a reach.
///
/// The wrist ranges are in the authors' frames (their sequences have 90
/// frames); they are scaled to normalised time (frame / 90), so they mean
/// the same at any frame rate or duration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrajectoryConfig {
    /// Sequence length, seconds (the real data's 3 s).
    pub duration_s: f64,
    /// Frames per second; the sequence has round(duration_s * fps) frames.
    pub fps: f64,
    /// The last this-many seconds are labelled `no_grasp` (hand-object contact).
    pub no_grasp_tail_s: f64,
    /// The camera stops this far short of the target (the wrist camera sits
    /// behind the grasp point; the authors used 0.2 m with their far camera).
    pub standoff_m: f64,
    /// Frame count the wrist ranges below are expressed in.
    pub authors_frames: f64,
    /// Pronation-supination onset, authors' frames, uniform.
    pub ps_onset_frames: [f64; 2],
    /// Pronation-supination duration, authors' frames, uniform.
    pub ps_duration_frames: [f64; 2],
    /// Fraction of the pronation-supination angle executed, uniform.
    pub ps_fraction: [f64; 2],
    /// Flexion-extension onset, authors' frames, uniform.
    pub fe_onset_frames: [f64; 2],
    /// Fraction of the remaining flexion-extension angle closed per authors'
    /// frame (the final amount is 1 - (1 - rate)^frames_left).
    pub fe_rate_per_frame: f64,
    pub wrist_timing: WristTiming,
    /// Candidate scenes drawn before giving up on a sequence.
    pub max_attempts: u32,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        TrajectoryConfig {
            duration_s: 3.0,
            fps: 30.0,
            no_grasp_tail_s: 0.5,
            standoff_m: 0.12,
            authors_frames: 90.0,
            ps_onset_frames: [25.0, 45.0],
            ps_duration_frames: [20.0, 45.0],
            ps_fraction: [0.7, 1.0],
            fe_onset_frames: [75.0, 80.0],
            fe_rate_per_frame: 0.1,
            wrist_timing: WristTiming::Authors,
            max_attempts: 1000,
        }
    }
}

impl TrajectoryConfig {
    /// Frames of a sequence lasting `duration_s`.
    pub fn frame_count(&self, duration_s: f64) -> Result<usize> {
        let n = (duration_s * self.fps).round();
        if !(1.0..=10_000_000.0).contains(&n) {
            return Err(ConfigError::FrameCount {
                duration_s,
                fps: self.fps,
                frames: n,
            });
        }
        Ok(n as usize)
    }

    // Negated comparisons: a NaN must fail these checks.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn validate(&self) -> Result<()> {
        if !(self.fps.is_finite() && self.fps > 0.0) {
            return Err(ConfigError::rule(
                "plan.trajectory.fps",
                format!("must be positive, got {}", self.fps),
            ));
        }
        if !(self.duration_s.is_finite() && self.duration_s > 0.0) {
            return Err(ConfigError::rule(
                "plan.trajectory.duration_s",
                format!("must be positive, got {}", self.duration_s),
            ));
        }
        self.frame_count(self.duration_s)?;
        if !(self.no_grasp_tail_s >= 0.0 && self.no_grasp_tail_s < self.duration_s) {
            return Err(ConfigError::rule(
                "plan.trajectory.no_grasp_tail_s",
                format!(
                    "({}) must be in [0, duration_s = {})",
                    self.no_grasp_tail_s, self.duration_s
                ),
            ));
        }
        if !(self.standoff_m >= 0.0) {
            return Err(ConfigError::rule(
                "plan.trajectory.standoff_m",
                format!("must be >= 0, got {}", self.standoff_m),
            ));
        }
        if !(self.authors_frames > 0.0) {
            return Err(ConfigError::rule(
                "plan.trajectory.authors_frames",
                "must be positive",
            ));
        }
        for (name, r) in [
            ("ps_onset_frames", self.ps_onset_frames),
            ("ps_duration_frames", self.ps_duration_frames),
            ("ps_fraction", self.ps_fraction),
            ("fe_onset_frames", self.fe_onset_frames),
        ] {
            if !(r[0].is_finite() && r[1].is_finite() && 0.0 <= r[0] && r[0] <= r[1]) {
                return Err(ConfigError::rule(
                    format!("plan.trajectory.{name}"),
                    format!("must be a range [min, max] of non-negative values, got {r:?}"),
                ));
            }
        }
        if !((0.0..=1.0).contains(&self.fe_rate_per_frame)) {
            return Err(ConfigError::rule(
                "plan.trajectory.fe_rate_per_frame",
                format!("must be in [0, 1], got {}", self.fe_rate_per_frame),
            ));
        }
        if self.max_attempts == 0 {
            return Err(ConfigError::rule(
                "plan.trajectory.max_attempts",
                "must be >= 1",
            ));
        }
        Ok(())
    }

    /// Number of trailing `no_grasp` frames among `n`.
    pub fn tail_frames(&self, n: usize) -> usize {
        ((self.no_grasp_tail_s * self.fps).round() as usize).min(n)
    }
}

/// Minimum-jerk progress s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5, clamped to [0, 1].
pub fn min_jerk(tau: f64) -> f64 {
    let t = tau.clamp(0.0, 1.0);
    t * t * t * (10.0 + t * (-15.0 + 6.0 * t))
}

/// ds/dtau = 30 tau^2 (1 - tau)^2 (zero outside [0, 1]).
pub fn min_jerk_velocity(tau: f64) -> f64 {
    if !(0.0..=1.0).contains(&tau) {
        return 0.0;
    }
    30.0 * tau * tau * (1.0 - tau) * (1.0 - tau)
}

/// d2s/dtau2 = 60 tau - 180 tau^2 + 120 tau^3 (zero outside [0, 1]).
pub fn min_jerk_acceleration(tau: f64) -> f64 {
    if !(0.0..=1.0).contains(&tau) {
        return 0.0;
    }
    tau * (60.0 + tau * (-180.0 + 120.0 * tau))
}

/// A minimum-jerk ramp from 0 to 1 over the window [start, start + length]
/// of normalised time.
pub fn min_jerk_window(tau: f64, start: f64, length: f64) -> f64 {
    if length <= 0.0 {
        return if tau >= start { 1.0 } else { 0.0 };
    }
    min_jerk((tau - start) / length)
}

/// A linear ramp from 0 to 1 over [start, start + length] (the authors'
/// constant per-frame wrist rotation).
pub fn linear_window(tau: f64, start: f64, length: f64) -> f64 {
    if length <= 0.0 {
        return if tau >= start { 1.0 } else { 0.0 };
    }
    ((tau - start) / length).clamp(0.0, 1.0)
}

/// Minimum-jerk path through one via-point, in closed form.
///
/// With zero velocity and acceleration at both ends, the jerk-optimal path
/// through `via` at time `tau1` is x(tau) = x0 + D s(tau) + mu h(tau), where
/// D = xf - x0, s is the plain minimum-jerk law and h a quintic plus
/// (tau - tau1)_+^5. Position, velocity, acceleration, jerk and snap are all
/// continuous at the via-point; only the fifth derivative jumps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViaPath {
    pub start: Vector3<f64>,
    pub end: Vector3<f64>,
    pub via: Vector3<f64>,
    pub tau1: f64,
    w: [f64; 3],
    mu: Vector3<f64>,
}

impl ViaPath {
    /// `tau1` must lie strictly inside (0, 1).
    pub fn new(start: Vector3<f64>, via: Vector3<f64>, end: Vector3<f64>, tau1: f64) -> ViaPath {
        let tau1 = tau1.clamp(0.05, 0.95);
        let r = 1.0 - tau1;
        let (r3, r4, r5) = (r.powi(3), r.powi(4), r.powi(5));
        // w = M^-1 (-r^5, -5 r^4, -20 r^3) with M the end-condition matrix
        // [[1,1,1],[3,4,5],[6,12,20]] of the tau^3..tau^5 coefficients.
        let w = [
            -10.0 * r5 + 20.0 * r4 - 10.0 * r3,
            15.0 * r5 - 35.0 * r4 + 20.0 * r3,
            -6.0 * r5 + 15.0 * r4 - 10.0 * r3,
        ];
        let h1 = poly345(&w, tau1);
        let mu = (via - start - (end - start) * min_jerk(tau1)) / h1;
        ViaPath {
            start,
            end,
            via,
            tau1,
            w,
            mu,
        }
    }

    fn h(&self, tau: f64) -> [f64; 3] {
        let [w3, w4, w5] = self.w;
        let t = tau;
        let d = (t - self.tau1).max(0.0);
        let hp = t * t * t * (w3 + t * (w4 + t * w5)) + d.powi(5);
        let hv = t * t * (3.0 * w3 + t * (4.0 * w4 + 5.0 * w5 * t)) + 5.0 * d.powi(4);
        let ha = t * (6.0 * w3 + t * (12.0 * w4 + 20.0 * w5 * t)) + 20.0 * d.powi(3);
        [hp, hv, ha]
    }
}

fn poly345(w: &[f64; 3], t: f64) -> f64 {
    t * t * t * (w[0] + t * (w[1] + t * w[2]))
}

/// The shape of a camera path; evaluated with the minimum-jerk time law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Path {
    /// x0 + (xf - x0) s(tau).
    Straight {
        start: Vector3<f64>,
        end: Vector3<f64>,
    },
    /// Quadratic Bezier (start, control, end) travelled with parameter s(tau).
    Curved {
        start: Vector3<f64>,
        control: Vector3<f64>,
        end: Vector3<f64>,
    },
    /// Minimum jerk through a via-point.
    Via(ViaPath),
}

impl Path {
    pub fn start(&self) -> Vector3<f64> {
        match self {
            Path::Straight { start, .. } | Path::Curved { start, .. } => *start,
            Path::Via(v) => v.start,
        }
    }

    pub fn end(&self) -> Vector3<f64> {
        match self {
            Path::Straight { end, .. } | Path::Curved { end, .. } => *end,
            Path::Via(v) => v.end,
        }
    }

    /// Position at normalised time tau (clamped to [0, 1]).
    pub fn position(&self, tau: f64) -> Vector3<f64> {
        let tau = tau.clamp(0.0, 1.0);
        match self {
            Path::Straight { start, end } => start + (end - start) * min_jerk(tau),
            Path::Curved {
                start,
                control,
                end,
            } => bezier(start, control, end, min_jerk(tau)),
            Path::Via(v) => v.start + (v.end - v.start) * min_jerk(tau) + v.mu * v.h(tau)[0],
        }
    }

    /// d position / d tau (divide by the duration for m/s).
    pub fn velocity(&self, tau: f64) -> Vector3<f64> {
        let tau = tau.clamp(0.0, 1.0);
        let ds = min_jerk_velocity(tau);
        match self {
            Path::Straight { start, end } => (end - start) * ds,
            Path::Curved {
                start,
                control,
                end,
            } => bezier_tangent(start, control, end, min_jerk(tau)) * ds,
            Path::Via(v) => (v.end - v.start) * ds + v.mu * v.h(tau)[1],
        }
    }

    /// d2 position / d tau2.
    pub fn acceleration(&self, tau: f64) -> Vector3<f64> {
        let tau = tau.clamp(0.0, 1.0);
        let (s, ds, dds) = (
            min_jerk(tau),
            min_jerk_velocity(tau),
            min_jerk_acceleration(tau),
        );
        match self {
            Path::Straight { start, end } => (end - start) * dds,
            Path::Curved {
                start,
                control,
                end,
            } => {
                let second = (start - control * 2.0 + end) * 2.0;
                bezier_tangent(start, control, end, s) * dds + second * (ds * ds)
            }
            Path::Via(v) => (v.end - v.start) * dds + v.mu * v.h(tau)[2],
        }
    }

    /// `n + 1` points along the path at evenly spaced times (a polyline for
    /// collision checks).
    pub fn polyline(&self, n: usize) -> Vec<Vector3<f64>> {
        match self {
            Path::Straight { start, end } => vec![*start, *end],
            _ => (0..=n.max(1))
                .map(|k| self.position(k as f64 / n.max(1) as f64))
                .collect(),
        }
    }
}

fn bezier(p0: &Vector3<f64>, p1: &Vector3<f64>, p2: &Vector3<f64>, s: f64) -> Vector3<f64> {
    let u = 1.0 - s;
    p0 * (u * u) + p1 * (2.0 * u * s) + p2 * (s * s)
}

fn bezier_tangent(p0: &Vector3<f64>, p1: &Vector3<f64>, p2: &Vector3<f64>, s: f64) -> Vector3<f64> {
    (p1 - p0) * (2.0 * (1.0 - s)) + (p2 - p1) * (2.0 * s)
}

/// Normalised time of frame `i` of `n`: frame 0 is the start, frame n-1 the
/// end. A single frame sits at the start.
pub fn frame_tau(i: usize, n: usize) -> f64 {
    if n <= 1 {
        0.0
    } else {
        i as f64 / (n - 1) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn min_jerk_boundary_values_and_peak() {
        assert_eq!(min_jerk(0.0), 0.0);
        assert_eq!(min_jerk(1.0), 1.0);
        assert_eq!(min_jerk(0.5), 0.5);
        assert_eq!(min_jerk_velocity(0.0), 0.0);
        assert_eq!(min_jerk_velocity(1.0), 0.0);
        assert_eq!(min_jerk_acceleration(0.0), 0.0);
        assert!(min_jerk_acceleration(1.0).abs() < 1e-12);
        assert!((min_jerk_velocity(0.5) - 1.875).abs() < 1e-15);
    }

    #[test]
    fn via_path_passes_through_its_points_with_zero_end_velocity() {
        let p = Path::Via(ViaPath::new(
            v(0.0, 0.0, 0.8),
            v(0.3, 0.1, 1.2),
            v(0.7, 0.0, 0.9),
            0.4,
        ));
        assert!((p.position(0.0) - v(0.0, 0.0, 0.8)).norm() < 1e-12);
        assert!((p.position(0.4) - v(0.3, 0.1, 1.2)).norm() < 1e-12);
        assert!((p.position(1.0) - v(0.7, 0.0, 0.9)).norm() < 1e-12);
        assert!(p.velocity(0.0).norm() < 1e-12 && p.velocity(1.0).norm() < 1e-9);
        assert!(p.acceleration(0.0).norm() < 1e-12 && p.acceleration(1.0).norm() < 1e-9);
        assert!(p.velocity(0.4).norm() > 0.1, "the via-point is not a stop");
    }

    #[test]
    fn via_path_velocity_matches_finite_differences() {
        let p = Path::Via(ViaPath::new(
            v(0.0, 0.0, 0.8),
            v(0.3, 0.1, 1.2),
            v(0.7, 0.0, 0.9),
            0.45,
        ));
        for k in 1..100 {
            let t = k as f64 / 100.0;
            let h = 1e-6;
            let fd = (p.position(t + h) - p.position(t - h)) / (2.0 * h);
            assert!((fd - p.velocity(t)).norm() < 1e-6, "tau {t}");
            let fa = (p.velocity(t + h) - p.velocity(t - h)) / (2.0 * h);
            assert!((fa - p.acceleration(t)).norm() < 1e-5, "tau {t}");
        }
    }

    #[test]
    fn curved_path_ends_tangent_to_its_last_leg() {
        let (a, c, b) = (v(0.0, 0.0, 0.0), v(0.2, 0.0, 0.3), v(0.5, 0.0, 0.2));
        let p = Path::Curved {
            start: a,
            control: c,
            end: b,
        };
        let near_end = p.position(1.0 - 1e-4);
        let dir = (b - near_end).normalize();
        assert!((dir - (b - c).normalize()).norm() < 1e-3);
        assert_eq!(p.position(1.0), b);
    }
}
