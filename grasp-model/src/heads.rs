//! Classifier heads on per-frame features (the paper's Sec. III):
//! - FC: one linear layer, feature_dim -> classes, applied to each frame;
//! - LSTM: a one-layer LSTM (256 hidden units) over the frames of a sequence,
//!   then a linear layer, hidden -> classes, at every step;
//! - trace: one linear layer on the frame and the approach's decaying mean
//!   of features (`crate::trace`), 2 feature_dim -> classes: a head with
//!   the approach's history that runs frame by frame at any frame rate.
//!
//! Parameter names follow PyTorch (`fc.weight`, `lstm.weight_ih_l0`, ...,
//! gate order i, f, g, o), so heads can be exchanged with the authors' code.
//! The LSTM projects every input step in one matrix product, then runs the
//! recurrence as one fused op (`ops::lstm`).

use crate::ops::linear::linear;
use crate::ops::lstm::lstm_recurrence;
use candle_core::{Result, Tensor};
use candle_nn::VarBuilder;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeadKind {
    Fc,
    Lstm,
    Trace,
}

impl HeadKind {
    pub const ALL: [HeadKind; 3] = [HeadKind::Fc, HeadKind::Lstm, HeadKind::Trace];

    pub fn name(self) -> &'static str {
        match self {
            HeadKind::Fc => "fc",
            HeadKind::Lstm => "lstm",
            HeadKind::Trace => "trace",
        }
    }

    /// The head by its [`name`](HeadKind::name).
    pub fn from_name(name: &str) -> Option<HeadKind> {
        HeadKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Whether the head classifies each frame as it comes, as the hand's
    /// streaming loop (`hannes-run`) needs: an LSTM head reads a sequence
    /// at the frame rate it was trained on, which a live camera's dropped
    /// frames do not keep; the trace head keeps its history in seconds.
    pub fn classifies_frames(self) -> bool {
        match self {
            HeadKind::Fc | HeadKind::Trace => true,
            HeadKind::Lstm => false,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HeadConfig {
    pub kind: HeadKind,
    pub feature_dim: usize,
    pub classes: usize,
    pub lstm_hidden: usize,
    /// A sequence head's step rate: the frame rate of the sequences it was
    /// trained on (frames/s). Sequences at another rate are resampled to it
    /// ([`HeadConfig::steps`]); a head that classifies frames has none, and
    /// neither do checkpoints written before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step_hz: Option<f64>,
    /// A trace head's time constant (s, [`crate::trace`]); none for the
    /// others.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trace_s: Option<f64>,
}

impl HeadConfig {
    /// The width of the final linear layer's input.
    pub fn fc_inputs(&self) -> usize {
        match self.kind {
            HeadKind::Fc => self.feature_dim,
            HeadKind::Lstm => self.lstm_hidden,
            HeadKind::Trace => 2 * self.feature_dim,
        }
    }

    /// A fresh trace for a trace head, none for the others; a trace head
    /// without a usable time constant is refused.
    pub fn new_trace(&self) -> Result<Option<crate::trace::FeatureTrace>> {
        if self.kind != HeadKind::Trace {
            return Ok(None);
        }
        let tau = self.trace_s.unwrap_or(f64::NAN);
        crate::trace::FeatureTrace::new(tau)
            .map(Some)
            .map_err(|e| candle_core::Error::Msg(format!("head.trace_s: {e}")))
    }

    /// The frames of a sequence, at times `times_s` (seconds, ascending),
    /// that this head reads: all of them for a head that classifies frames
    /// or has no step rate; otherwise the frame nearest each tick of its
    /// step rate from the first frame on, each at most once. A sequence
    /// recorded faster than training's is thinned to training's rate, so
    /// that the recurrence covers the same time per step; a slower one
    /// keeps every frame.
    pub fn steps(&self, times_s: &[f64]) -> Vec<usize> {
        match self.step_hz {
            Some(hz) if !self.kind.classifies_frames() => frames_at_rate(times_s, hz),
            _ => (0..times_s.len()).collect(),
        }
    }
}

/// The indices of `times_s` (ascending) nearest each tick `t0 + k / hz`
/// up to the last frame's time, without repeats; every index for a rate
/// that is not positive and finite.
pub fn frames_at_rate(times_s: &[f64], hz: f64) -> Vec<usize> {
    let n = times_s.len();
    if n == 0 || !(hz.is_finite() && hz > 0.0) {
        return (0..n).collect();
    }
    let period = 1.0 / hz;
    let (first, last) = (times_s[0], times_s[n - 1]);
    if !(first.is_finite() && last.is_finite()) {
        return (0..n).collect(); // a recording without a usable clock
    }
    // Ticks far denser than the frames pick every frame; this also bounds
    // the loop below for a rate out of all proportion (a corrupt file).
    if (last - first) * hz > 2.0 * n as f64 {
        return (0..n).collect();
    }
    let mut picked: Vec<usize> = Vec::new();
    let mut i = 0;
    // A closed form for each tick's time, not a running sum: no drift.
    for k in 0.. {
        let tick = first + k as f64 * period;
        // No tick after the last frame (up to rounding): a recording that
        // ends between two ticks is read to its last tick.
        if tick - last > 1e-6 * period {
            break;
        }
        // The nearest frame to the tick among those not passed yet; a tie
        // goes to the later frame.
        while i + 1 < n && (times_s[i + 1] - tick).abs() <= (times_s[i] - tick).abs() {
            i += 1;
        }
        if picked.last() != Some(&i) {
            picked.push(i);
        }
    }
    picked
}

/// The recurrent state carried between chunks of a sequence.
#[derive(Debug, Clone)]
pub struct LstmState {
    pub h: Tensor,
    pub c: Tensor,
}

impl LstmState {
    pub fn detach(&self) -> LstmState {
        LstmState {
            h: self.h.detach(),
            c: self.c.detach(),
        }
    }
}

#[derive(Debug, Clone)]
struct Lstm {
    w_ih: Tensor,
    w_hh: Tensor,
    /// `bias_ih + bias_hh`: both only ever appear summed.
    bias: Tensor,
    hidden: usize,
}

/// A linear layer's parameters, applied with [`linear`] so that cached
/// (constant) inputs get no gradient.
#[derive(Debug, Clone)]
struct Fc {
    weight: Tensor,
    bias: Tensor,
}

impl Fc {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        linear(x, &self.weight, &self.bias)
    }
}

#[derive(Debug, Clone)]
pub struct Head {
    pub cfg: HeadConfig,
    lstm: Option<Lstm>,
    fc: Fc,
}
impl Head {
    /// Builds the head from `vb` (a VarMap while training, a checkpoint when
    /// loading).
    pub fn new(cfg: HeadConfig, vb: VarBuilder) -> Result<Head> {
        let fc_in = cfg.fc_inputs();
        let fc = Fc {
            weight: vb.get((cfg.classes, fc_in), "fc.weight")?,
            bias: vb.get(cfg.classes, "fc.bias")?,
        };
        let lstm = match cfg.kind {
            HeadKind::Fc | HeadKind::Trace => None,
            HeadKind::Lstm => {
                let h = cfg.lstm_hidden;
                let vb = vb.pp("lstm");
                let w_ih = vb.get((4 * h, cfg.feature_dim), "weight_ih_l0")?;
                let w_hh = vb.get((4 * h, h), "weight_hh_l0")?;
                let b_ih = vb.get(4 * h, "bias_ih_l0")?;
                let b_hh = vb.get(4 * h, "bias_hh_l0")?;
                Some(Lstm {
                    w_ih,
                    w_hh,
                    bias: (b_ih + b_hh)?,
                    hidden: h,
                })
            }
        };
        Ok(Head { cfg, lstm, fc })
    }

    /// Parameter names and shapes, for deterministic initialisation.
    pub fn parameter_shapes(cfg: &HeadConfig) -> Vec<(String, Vec<usize>)> {
        let h = cfg.lstm_hidden;
        let mut out = Vec::new();
        if cfg.kind == HeadKind::Lstm {
            out.push(("lstm.weight_ih_l0".into(), vec![4 * h, cfg.feature_dim]));
            out.push(("lstm.weight_hh_l0".into(), vec![4 * h, h]));
            out.push(("lstm.bias_ih_l0".into(), vec![4 * h]));
            out.push(("lstm.bias_hh_l0".into(), vec![4 * h]));
        }
        out.push(("fc.weight".into(), vec![cfg.classes, cfg.fc_inputs()]));
        out.push(("fc.bias".into(), vec![cfg.classes]));
        out
    }

    /// PyTorch's default initialisation bound for a parameter: uniform in
    /// ±1/sqrt(fan_in) for `nn.Linear`, ±1/sqrt(hidden) for `nn.LSTM`.
    pub fn init_bound(cfg: &HeadConfig, name: &str) -> f64 {
        if name.starts_with("lstm.") {
            1.0 / (cfg.lstm_hidden as f64).sqrt()
        } else {
            1.0 / (cfg.fc_inputs() as f64).sqrt()
        }
    }

    /// Per-frame logits of independent rows `(N, I) -> (N, C)`, `I` =
    /// [`HeadConfig::fc_inputs`]: frames for the FC head, traced frames
    /// (`[f, m]`, [`crate::trace`]) for the trace head.
    pub fn forward_frames(&self, x: &Tensor) -> Result<Tensor> {
        self.fc.forward(x)
    }

    /// Logits of sequence batches `(B, T, D) -> (B, T, C)`, from a zero
    /// state for the LSTM, frame by frame for the FC head.
    pub fn forward_sequences(&self, x: &Tensor) -> Result<Tensor> {
        let (b, _, _) = x.dims3()?;
        match &self.lstm {
            None => self.fc.forward(x),
            Some(l) => {
                let state = l.zero_state(b, x)?;
                Ok(self.forward_chunk(x, &state)?.0)
            }
        }
    }

    /// Zero LSTM state for `batch` sequences.
    pub fn zero_state(&self, batch: usize, like: &Tensor) -> Result<Option<LstmState>> {
        self.lstm
            .as_ref()
            .map(|l| l.zero_state(batch, like))
            .transpose()
    }

    /// Runs one chunk `(B, T, D)` of sequences from `state`; returns the
    /// logits `(B, T, C)` and the final state (truncated back-propagation
    /// through time detaches it between chunks).
    pub fn forward_chunk(&self, x: &Tensor, state: &LstmState) -> Result<(Tensor, LstmState)> {
        let l = self
            .lstm
            .as_ref()
            .ok_or_else(|| candle_core::Error::Msg("forward_chunk needs an LSTM head".into()))?;
        let (hs, state) = l.run(x, state)?;
        Ok((self.fc.forward(&hs)?, state))
    }

    /// A copy whose weights are cut from any autograd graph, for inference:
    /// long sequences then build no graph at all.
    pub fn detached(&self) -> Head {
        Head {
            cfg: self.cfg,
            lstm: self.lstm.as_ref().map(|l| Lstm {
                w_ih: l.w_ih.detach(),
                w_hh: l.w_hh.detach(),
                bias: l.bias.detach(),
                hidden: l.hidden,
            }),
            fc: Fc {
                weight: self.fc.weight.detach(),
                bias: self.fc.bias.detach(),
            },
        }
    }
}

impl Lstm {
    fn zero_state(&self, batch: usize, like: &Tensor) -> Result<LstmState> {
        let z = Tensor::zeros((batch, self.hidden), like.dtype(), like.device())?;
        Ok(LstmState { h: z.clone(), c: z })
    }

    /// Returns the hidden states `(B, T, H)` and the final state: the input
    /// projection of every step in one product, then the fused recurrence.
    fn run(&self, x: &Tensor, state: &LstmState) -> Result<(Tensor, LstmState)> {
        let t = x.dim(1)?;
        let h = self.hidden;
        if t == 0 {
            let (b, _, _) = x.dims3()?;
            let empty = Tensor::zeros((b, 0, h), x.dtype(), x.device())?;
            return Ok((empty, state.clone()));
        }
        let gates_x = linear(x, &self.w_ih, &self.bias)?;
        let state0 = Tensor::cat(&[&state.h, &state.c], 1)?;
        let out = lstm_recurrence(&gates_x, &self.w_hh, &state0)?;
        let last = out.narrow(1, t - 1, 1)?.squeeze(1)?;
        let state = LstmState {
            h: last.narrow(1, 0, h)?,
            c: last.narrow(1, h, h)?,
        };
        Ok((out.narrow(2, 0, h)?, state))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn times(n: usize, fps: f64) -> Vec<f64> {
        (0..n).map(|i| i as f64 / fps).collect()
    }

    #[test]
    fn a_faster_sequence_is_thinned_to_the_step_rate() {
        // 5 and 30 frames/s read at 2.5: every 2nd and every 12th frame.
        assert_eq!(frames_at_rate(&times(9, 5.0), 2.5), vec![0, 2, 4, 6, 8]);
        let picked = frames_at_rate(&times(61, 30.0), 2.5);
        assert_eq!(picked, (0..=60).step_by(12).collect::<Vec<_>>());
        // Starting late (a trimmed lead-in) changes nothing but the origin.
        let late: Vec<f64> = times(9, 5.0).iter().map(|t| t + 3.7).collect();
        assert_eq!(frames_at_rate(&late, 2.5), vec![0, 2, 4, 6, 8]);
    }

    #[test]
    fn the_same_or_a_slower_rate_keeps_every_frame() {
        for fps in [2.5, 2.0, 1.0] {
            assert_eq!(
                frames_at_rate(&times(7, fps), 2.5),
                (0..7).collect::<Vec<_>>()
            );
        }
        assert_eq!(
            frames_at_rate(&times(7, 30.0), 1e12),
            (0..7).collect::<Vec<_>>()
        );
    }

    #[test]
    fn jittered_frames_pick_the_nearest_to_each_tick() {
        // A live camera's irregular times, ticks at 0, 0.4, 0.8 and 1.2:
        // 1.21 is nearer the last than 1.18.
        let t = [0.0, 0.13, 0.31, 0.38, 0.52, 0.79, 0.95, 1.18, 1.21];
        assert_eq!(frames_at_rate(&t, 2.5), vec![0, 3, 5, 8]);
    }

    #[test]
    fn degenerate_inputs_keep_every_frame() {
        assert!(frames_at_rate(&[], 2.5).is_empty());
        assert_eq!(frames_at_rate(&[4.2], 2.5), vec![0]);
        for hz in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(frames_at_rate(&times(3, 5.0), hz), vec![0, 1, 2]);
        }
        // A recording whose frame rate reads 0 or NaN: times without end.
        for fps in [0.0, f64::NAN] {
            assert_eq!(frames_at_rate(&times(3, fps), 2.5), vec![0, 1, 2]);
        }
    }

    #[test]
    fn only_a_sequence_head_with_a_step_rate_is_resampled() {
        let cfg = |kind, step_hz| HeadConfig {
            kind,
            feature_dim: 4,
            classes: 5,
            lstm_hidden: 8,
            step_hz,
            trace_s: None,
        };
        let t = times(5, 5.0);
        assert_eq!(cfg(HeadKind::Lstm, Some(2.5)).steps(&t), vec![0, 2, 4]);
        assert_eq!(cfg(HeadKind::Lstm, None).steps(&t), vec![0, 1, 2, 3, 4]);
        assert_eq!(cfg(HeadKind::Fc, Some(2.5)).steps(&t), vec![0, 1, 2, 3, 4]);
    }
}
