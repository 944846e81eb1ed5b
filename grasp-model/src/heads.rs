//! Classifier heads on per-frame features (the paper's Sec. III):
//! - FC: one linear layer, feature_dim -> classes, applied to each frame;
//! - LSTM: a one-layer LSTM (256 hidden units) over the frames of a sequence,
//!   then a linear layer, hidden -> classes, at every step.
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
}

impl HeadKind {
    pub const ALL: [HeadKind; 2] = [HeadKind::Fc, HeadKind::Lstm];

    pub fn name(self) -> &'static str {
        match self {
            HeadKind::Fc => "fc",
            HeadKind::Lstm => "lstm",
        }
    }

    /// The head by its [`name`](HeadKind::name).
    pub fn from_name(name: &str) -> Option<HeadKind> {
        HeadKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Whether the head classifies each frame on its own, as the hand's
    /// streaming loop (`hannes-run`) needs: an LSTM head reads a sequence
    /// at the frame rate it was trained on, which a live camera's dropped
    /// frames do not keep.
    pub fn classifies_frames(self) -> bool {
        match self {
            HeadKind::Fc => true,
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
        let fc_in = match cfg.kind {
            HeadKind::Fc => cfg.feature_dim,
            HeadKind::Lstm => cfg.lstm_hidden,
        };
        let fc = Fc {
            weight: vb.get((cfg.classes, fc_in), "fc.weight")?,
            bias: vb.get(cfg.classes, "fc.bias")?,
        };
        let lstm = match cfg.kind {
            HeadKind::Fc => None,
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
        let fc_in = match cfg.kind {
            HeadKind::Fc => cfg.feature_dim,
            HeadKind::Lstm => {
                out.push(("lstm.weight_ih_l0".into(), vec![4 * h, cfg.feature_dim]));
                out.push(("lstm.weight_hh_l0".into(), vec![4 * h, h]));
                out.push(("lstm.bias_ih_l0".into(), vec![4 * h]));
                out.push(("lstm.bias_hh_l0".into(), vec![4 * h]));
                h
            }
        };
        out.push(("fc.weight".into(), vec![cfg.classes, fc_in]));
        out.push(("fc.bias".into(), vec![cfg.classes]));
        out
    }

    /// PyTorch's default initialisation bound for a parameter: uniform in
    /// ±1/sqrt(fan_in) for `nn.Linear`, ±1/sqrt(hidden) for `nn.LSTM`.
    pub fn init_bound(cfg: &HeadConfig, name: &str) -> f64 {
        if name.starts_with("lstm.") {
            1.0 / (cfg.lstm_hidden as f64).sqrt()
        } else {
            let fan_in = match cfg.kind {
                HeadKind::Fc => cfg.feature_dim,
                HeadKind::Lstm => cfg.lstm_hidden,
            };
            1.0 / (fan_in as f64).sqrt()
        }
    }

    /// Per-frame logits of independent frames `(N, D) -> (N, C)` (FC head).
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
