//! The approach's history for a head that runs frame by frame (the `trace`
//! head): an exponentially decaying mean of the features seen since the
//! approach began, kept in seconds rather than in frames, so that a live
//! camera's dropped or irregular frames weigh what they span.
//!
//! After a frame at time `t` with features `f`, the trace `m` is
//! `m <- m + a (f - m)`, `a = 1 - exp(-(t - t_prev) / tau)`: a closed form
//! of the decay over the gap, whatever its length. The first frame starts
//! it (`m = f`); a frame at the same time as the last adds nothing to it;
//! a clock that runs back (or is not a number) starts it again. The head
//! reads `[f, m]`: the frame, and what the approach has shown so far.
//!
//! One implementation for the three readers: the trainer traces the cached
//! features of each training sequence ([`traced_rows`]), evaluation each
//! video's, and `hannes-run` each approach frame by frame
//! ([`FeatureTrace::push`]).

/// Why a time constant cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the trace's time constant must be a positive finite number of seconds, not {0}")]
pub struct InvalidTimeConstant(pub f64);

/// The running trace of one approach.
#[derive(Debug, Clone)]
pub struct FeatureTrace {
    time_constant_s: f64,
    /// `[f, m]` of the last frame pushed.
    out: Vec<f32>,
    last_s: Option<f64>,
}

impl FeatureTrace {
    pub fn new(time_constant_s: f64) -> Result<Self, InvalidTimeConstant> {
        check_time_constant(time_constant_s)?;
        Ok(FeatureTrace {
            time_constant_s,
            out: Vec::new(),
            last_s: None,
        })
    }

    /// Forgets the approach: the next frame starts a new trace.
    pub fn reset(&mut self) {
        self.last_s = None;
    }

    /// Adds the frame `features` seen at `time_s` and returns the head's
    /// input `[features, trace]` (twice the features' length).
    pub fn push(&mut self, time_s: f64, features: &[f32]) -> &[f32] {
        let dim = features.len();
        let weight = match self.last_s {
            Some(last) if self.out.len() == 2 * dim => {
                new_frame_weight(time_s - last, self.time_constant_s)
            }
            _ => 1.0,
        };
        if self.out.len() != 2 * dim {
            self.out = vec![0.0; 2 * dim];
        }
        let (frame, trace) = self.out.split_at_mut(dim);
        frame.copy_from_slice(features);
        for (m, f) in trace.iter_mut().zip(features) {
            *m = if weight >= 1.0 {
                *f
            } else {
                (f64::from(*m) + weight * (f64::from(*f) - f64::from(*m))) as f32
            };
        }
        // A clock that ran back starts the trace again from this frame.
        self.last_s = Some(time_s).filter(|t| t.is_finite());
        &self.out
    }
}

/// The weight of a frame `dt` seconds after the last: `1 - exp(-dt / tau)`
/// (by `expm1`, exact for gaps far shorter than `tau`); 0 for the same
/// instant, 1 (a fresh start) for a gap that is negative or not a number.
pub fn new_frame_weight(dt: f64, time_constant_s: f64) -> f64 {
    if dt == 0.0 {
        0.0
    } else if dt > 0.0 {
        // +inf gives exactly 1.
        -(-dt / time_constant_s).exp_m1()
    } else {
        1.0
    }
}

/// `[f, m]` of every row of one sequence: `rows` holds `times_s.len()`
/// rows of `dim` features in time order; the result twice as wide.
pub fn traced_rows(times_s: &[f64], rows: &[f32], dim: usize, time_constant_s: f64) -> Vec<f32> {
    let mut trace = FeatureTrace {
        time_constant_s,
        out: Vec::new(),
        last_s: None,
    };
    let mut out = Vec::with_capacity(2 * rows.len());
    for (t, row) in times_s.iter().zip(rows.chunks_exact(dim.max(1))) {
        out.extend_from_slice(trace.push(*t, row));
    }
    out
}

pub fn check_time_constant(time_constant_s: f64) -> Result<(), InvalidTimeConstant> {
    if time_constant_s.is_finite() && time_constant_s > 0.0 {
        Ok(())
    } else {
        Err(InvalidTimeConstant(time_constant_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trace_of(times: &[f64], values: &[f32], tau: f64) -> Vec<f32> {
        traced_rows(times, values, 1, tau)
            .chunks(2)
            .map(|r| r[1])
            .collect()
    }

    #[test]
    fn the_first_frame_starts_the_trace_and_the_frame_passes_through() {
        let out = traced_rows(&[0.0, 0.4], &[1.0, 2.0, 3.0, 4.0], 2, 1.0);
        assert_eq!(&out[..4], &[1.0, 2.0, 1.0, 2.0]);
        assert_eq!(&out[4..6], &[3.0, 4.0]);
    }

    #[test]
    fn the_decay_is_the_closed_form_of_the_gap_whatever_the_frame_rate() {
        // From 0 to 1 over one second: 1 - e^-1 whether in one step or 30.
        let one = trace_of(&[0.0, 1.0], &[0.0, 1.0], 1.0)[1];
        let times: Vec<f64> = (0..=30).map(|i| i as f64 / 30.0).collect();
        let mut values = vec![1.0f32; 31];
        values[0] = 0.0;
        let many = *trace_of(&times, &values, 1.0).last().unwrap();
        let want = 1.0 - (-1.0f64).exp();
        assert!((f64::from(one) - want).abs() < 1e-6, "{one}");
        assert!((f64::from(many) - want).abs() < 1e-5, "{many}");
    }

    #[test]
    fn extreme_gaps_and_time_constants() {
        // A gap far shorter than tau: expm1 keeps the tiny weight exact.
        assert!((new_frame_weight(1e-9, 1e3) - 1e-12).abs() < 1e-24);
        // Far longer: the trace is the new frame.
        assert_eq!(new_frame_weight(1e6, 1e-3), 1.0);
        assert_eq!(new_frame_weight(f64::INFINITY, 1.0), 1.0);
        // The same instant adds nothing; a clock run back or NaN restarts.
        assert_eq!(new_frame_weight(0.0, 1.0), 0.0);
        assert_eq!(new_frame_weight(-0.5, 1.0), 1.0);
        assert_eq!(new_frame_weight(f64::NAN, 1.0), 1.0);
        assert_eq!(trace_of(&[0.0, 0.0], &[1.0, 5.0], 1.0), vec![1.0, 1.0]);
        assert_eq!(trace_of(&[3.0, 1.0], &[1.0, 5.0], 1.0), vec![1.0, 5.0]);
        assert_eq!(trace_of(&[f64::NAN, 1.0], &[1.0, 5.0], 1.0), vec![1.0, 5.0]);
    }

    #[test]
    fn a_time_constant_must_be_positive_and_finite() {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(FeatureTrace::new(bad).is_err(), "{bad}");
        }
        assert!(FeatureTrace::new(1e-6).is_ok());
    }

    #[test]
    fn a_reset_starts_the_next_approach_afresh() {
        let mut t = FeatureTrace::new(1.0).unwrap();
        t.push(0.0, &[1.0]);
        t.push(0.5, &[3.0]);
        t.reset();
        assert_eq!(t.push(7.0, &[9.0]), &[9.0, 9.0]);
        // A frame of another width starts afresh too.
        assert_eq!(t.push(7.5, &[1.0, 2.0]), &[1.0, 2.0, 1.0, 2.0]);
    }

    #[test]
    fn streaming_and_whole_sequence_agree() {
        let times = [0.0, 0.13, 0.31, 0.9, 0.95];
        let rows: Vec<f32> = (0..10).map(|i| (i as f32).sin()).collect();
        let whole = traced_rows(&times, &rows, 2, 0.7);
        let mut t = FeatureTrace::new(0.7).unwrap();
        let streamed: Vec<f32> = times
            .iter()
            .zip(rows.chunks(2))
            .flat_map(|(s, r)| t.push(*s, r).to_vec())
            .collect();
        assert_eq!(whole, streamed);
    }
}
