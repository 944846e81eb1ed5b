//! Classifier heads on per-frame features (the paper's Sec. III):
//! - FC: one linear layer, feature_dim -> classes, applied to each frame;
//! - LSTM: a one-layer LSTM (256 hidden units) over the frames of a sequence,
//!   then a linear layer, hidden -> classes, at every step.
//!
//! Parameter names follow PyTorch (`fc.weight`, `lstm.weight_ih_l0`, ...,
//! gate order i, f, g, o), so heads can be exchanged with the authors' code.
//! The LSTM projects every input step in one matrix product before the
//! recurrence, which then only multiplies by `weight_hh`.

use candle_core::{Module, Result, Tensor, D};
use candle_nn::VarBuilder;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum HeadKind {
    Fc,
    Lstm,
}

impl HeadKind {
    pub fn name(self) -> &'static str {
        match self {
            HeadKind::Fc => "fc",
            HeadKind::Lstm => "lstm",
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
    w_hh_t: Tensor,
    bias: Tensor,
    hidden: usize,
}

#[derive(Debug, Clone)]
pub struct Head {
    pub cfg: HeadConfig,
    lstm: Option<Lstm>,
    fc: candle_nn::Linear,
}

impl Head {
    /// Builds the head from `vb` (a VarMap while training, a checkpoint when
    /// loading).
    pub fn new(cfg: HeadConfig, vb: VarBuilder) -> Result<Head> {
        let fc_in = match cfg.kind {
            HeadKind::Fc => cfg.feature_dim,
            HeadKind::Lstm => cfg.lstm_hidden,
        };
        let fc = candle_nn::Linear::new(
            vb.get((cfg.classes, fc_in), "fc.weight")?,
            Some(vb.get(cfg.classes, "fc.bias")?),
        );
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
                    w_hh_t: w_hh.t()?,
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
                w_hh_t: l.w_hh_t.detach(),
                bias: l.bias.detach(),
                hidden: l.hidden,
            }),
            fc: candle_nn::Linear::new(
                self.fc.weight().detach(),
                self.fc.bias().map(Tensor::detach),
            ),
        }
    }
}

impl Lstm {
    fn zero_state(&self, batch: usize, like: &Tensor) -> Result<LstmState> {
        let z = Tensor::zeros((batch, self.hidden), like.dtype(), like.device())?;
        Ok(LstmState { h: z.clone(), c: z })
    }

    /// Returns the hidden states `(B, T, H)` and the final state.
    fn run(&self, x: &Tensor, state: &LstmState) -> Result<(Tensor, LstmState)> {
        let (b, t, d) = x.dims3()?;
        let h4 = 4 * self.hidden;
        // Input projection of every step at once, laid out time-major.
        let xi = x
            .reshape((b * t, d))?
            .matmul(&self.w_ih.t()?)?
            .broadcast_add(&self.bias)?
            .reshape((b, t, h4))?
            .transpose(0, 1)?
            .contiguous()?;
        let (mut h, mut c) = (state.h.clone(), state.c.clone());
        let mut outputs = Vec::with_capacity(t);
        for step in 0..t {
            let gates = (xi.get(step)? + h.matmul(&self.w_hh_t)?)?;
            let chunks = gates.chunk(4, D::Minus1)?;
            let i = candle_nn::ops::sigmoid(&chunks[0])?;
            let f = candle_nn::ops::sigmoid(&chunks[1])?;
            let g = chunks[2].tanh()?;
            let o = candle_nn::ops::sigmoid(&chunks[3])?;
            c = ((f * &c)? + (i * g)?)?;
            h = (o * c.tanh()?)?;
            outputs.push(h.clone());
        }
        let hs = Tensor::stack(&outputs, 1)?;
        Ok((hs, LstmState { h, c }))
    }
}
