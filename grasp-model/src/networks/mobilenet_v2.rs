//! MobileNetV2 (Sandler et al., 2018) exactly as torchvision builds it, with
//! torchvision's parameter names so that its checkpoints load unchanged.
//!
//! Two execution paths share the parameters:
//! - train mode: plain candle ops (differentiable), batch norm with batch
//!   statistics, the custom depthwise op with its backward;
//! - eval mode: batch norm folded into the convolution weights and fused
//!   inference kernels (depthwise, pointwise + bias + ReLU6 + residual). The
//!   folded weights are computed on the first eval call and cached; a train
//!   forward drops the cache, since an optimizer step will change weights.

use std::sync::{Arc, Mutex};

use candle_core::{Module, Result, Tensor, D};
use candle_nn::{Init, Linear, VarBuilder};
use rayon::prelude::*;

use super::batch_norm::BatchNorm2d;
use crate::ops::depthwise::{depthwise_conv3x3, depthwise_conv3x3_bias_act};
use crate::ops::pointwise::{im2col3x3, pointwise_conv, pointwise_conv_bias_act};

/// Architecture options, as torchvision's `mobilenet_v2(width_mult=..., num_classes=..., dropout=...)`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MobileNetV2Config {
    pub width_mult: f64,
    /// 1000 for ImageNet checkpoints.
    pub num_classes: usize,
    pub dropout: f64,
}

impl Default for MobileNetV2Config {
    fn default() -> Self {
        Self {
            width_mult: 1.0,
            num_classes: 1000,
            dropout: 0.2,
        }
    }
}

/// (expansion t, output channels c, repeats n, first stride s), from the paper's Table 2.
const INVERTED_RESIDUAL_SETTING: [(usize, usize, usize, usize); 7] = [
    (1, 16, 1, 1),
    (6, 24, 2, 2),
    (6, 32, 3, 2),
    (6, 64, 4, 2),
    (6, 96, 3, 1),
    (6, 160, 3, 2),
    (6, 320, 1, 1),
];

/// Rounds `v` to a multiple of `divisor` as torchvision's `_make_divisible`:
/// to the nearest multiple, at least `divisor`, never more than 10% down.
pub fn make_divisible(v: f64, divisor: usize) -> usize {
    let d = divisor as f64;
    let mut new_v = (((v + d / 2.0) as usize) / divisor * divisor).max(divisor);
    if (new_v as f64) < 0.9 * v {
        new_v += divisor;
    }
    new_v
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum ConvKind {
    /// Dense 3x3 (the stem).
    Full3x3,
    Depthwise3x3,
    Pointwise,
}

/// Convolution (no bias) + batch norm + optional ReLU6: torchvision's
/// `Conv2dNormActivation`, or the projection `Conv2d` + `BatchNorm2d` pair.
#[derive(Debug)]
struct ConvBn {
    weight: Tensor,
    bn: BatchNorm2d,
    kind: ConvKind,
    stride: usize,
    relu6: bool,
}

/// Parameter paths of one conv + bn pair.
struct ConvNames<'a> {
    conv: &'a str,
    bn: &'a str,
}

impl ConvBn {
    fn new(
        vb: &VarBuilder,
        names: ConvNames,
        (cin, cout): (usize, usize),
        kind: ConvKind,
        stride: usize,
        relu6: bool,
    ) -> Result<Self> {
        let shape = match kind {
            ConvKind::Full3x3 => (cout, cin, 3, 3),
            ConvKind::Depthwise3x3 => (cout, 1, 3, 3),
            ConvKind::Pointwise => (cout, cin, 1, 1),
        };
        // torchvision: kaiming_normal_(mode="fan_out"), fan_out = cout * kh * kw.
        let fan_out = (shape.0 * shape.2 * shape.3) as f64;
        let init = Init::Randn {
            mean: 0.0,
            stdev: (2.0 / fan_out).sqrt(),
        };
        let weight = vb.pp(names.conv).get_with_hints(shape, "weight", init)?;
        let bn = BatchNorm2d::new(cout, vb.pp(names.bn))?;
        Ok(Self {
            weight,
            bn,
            kind,
            stride,
            relu6,
        })
    }

    fn forward_train(&self, x: &Tensor) -> Result<Tensor> {
        let y = match self.kind {
            ConvKind::Full3x3 => x.conv2d(&self.weight, 1, self.stride, 1, 1)?,
            ConvKind::Depthwise3x3 => depthwise_conv3x3(x, &self.weight, self.stride)?,
            ConvKind::Pointwise => pointwise_conv(x, &self.weight)?,
        };
        let y = self.bn.forward_train(&y)?;
        if self.relu6 {
            y.clamp(0f32, 6f32)
        } else {
            Ok(y)
        }
    }

    /// Folds the batch norm into the weights: w' = w * scale, b' = shift.
    fn fold(&self) -> Result<FoldedConv> {
        let (scale, shift) = self.bn.fold()?;
        let c = scale.dim(0)?;
        let weight = self
            .weight
            .broadcast_mul(&scale.reshape((c, 1, 1, 1))?)?
            .detach()
            .contiguous()?;
        Ok(FoldedConv {
            weight,
            bias: shift.detach().contiguous()?,
            kind: self.kind,
            stride: self.stride,
            relu6: self.relu6,
        })
    }
}

/// An inference convolution with batch norm folded in.
#[derive(Debug)]
struct FoldedConv {
    weight: Tensor,
    bias: Tensor,
    kind: ConvKind,
    stride: usize,
    relu6: bool,
}

impl FoldedConv {
    fn forward(&self, x: &Tensor, residual: Option<&Tensor>) -> Result<Tensor> {
        match self.kind {
            ConvKind::Pointwise => {
                pointwise_conv_bias_act(x, &self.weight, &self.bias, residual, self.relu6)
            }
            ConvKind::Depthwise3x3 => {
                let y = depthwise_conv3x3_bias_act(
                    x,
                    &self.weight,
                    &self.bias,
                    self.stride,
                    self.relu6,
                )?;
                add_residual(y, residual)
            }
            ConvKind::Full3x3 => {
                // im2col, then the same fused matmul kernel as the 1x1 layers
                let cols = im2col3x3(x, self.stride)?;
                let cout = self.weight.dim(0)?;
                let w = self.weight.reshape((cout, cols.dim(1)?))?;
                pointwise_conv_bias_act(&cols, &w, &self.bias, residual, self.relu6)
            }
        }
    }
}

fn add_residual(y: Tensor, residual: Option<&Tensor>) -> Result<Tensor> {
    match residual {
        Some(r) => y + r,
        None => Ok(y),
    }
}

/// torchvision's `InvertedResidual`: optional 1x1 expansion, 3x3 depthwise,
/// linear 1x1 projection, identity shortcut when shapes allow.
#[derive(Debug)]
struct InvertedResidual {
    expand: Option<ConvBn>,
    depthwise: ConvBn,
    project: ConvBn,
    use_residual: bool,
}

impl InvertedResidual {
    fn new(vb: VarBuilder, cin: usize, cout: usize, stride: usize, t: usize) -> Result<Self> {
        let hidden = cin * t;
        let vb = vb.pp("conv");
        // Layer indices inside `conv` shift by one when there is no expansion.
        let mut i = 0;
        let mut next = || {
            i += 1;
            (i - 1).to_string()
        };
        let expand = if t != 1 {
            let idx = next();
            let names = ConvNames {
                conv: &format!("{idx}.0"),
                bn: &format!("{idx}.1"),
            };
            Some(ConvBn::new(
                &vb,
                names,
                (cin, hidden),
                ConvKind::Pointwise,
                1,
                true,
            )?)
        } else {
            None
        };
        let idx = next();
        let (conv, bn) = (format!("{idx}.0"), format!("{idx}.1"));
        let depthwise = ConvBn::new(
            &vb,
            ConvNames {
                conv: &conv,
                bn: &bn,
            },
            (hidden, hidden),
            ConvKind::Depthwise3x3,
            stride,
            true,
        )?;
        let (conv, bn) = (next(), next());
        let project = ConvBn::new(
            &vb,
            ConvNames {
                conv: &conv,
                bn: &bn,
            },
            (hidden, cout),
            ConvKind::Pointwise,
            1,
            false,
        )?;
        Ok(Self {
            expand,
            depthwise,
            project,
            use_residual: stride == 1 && cin == cout,
        })
    }

    fn forward_train(&self, x: &Tensor) -> Result<Tensor> {
        let mut y = x.clone();
        if let Some(e) = &self.expand {
            y = e.forward_train(&y)?;
        }
        let y = self.depthwise.forward_train(&y)?;
        let y = self.project.forward_train(&y)?;
        if self.use_residual {
            y + x
        } else {
            Ok(y)
        }
    }

    fn fold(&self) -> Result<FoldedBlock> {
        Ok(FoldedBlock {
            expand: self.expand.as_ref().map(ConvBn::fold).transpose()?,
            depthwise: self.depthwise.fold()?,
            project: self.project.fold()?,
            use_residual: self.use_residual,
        })
    }
}

#[derive(Debug)]
struct FoldedBlock {
    expand: Option<FoldedConv>,
    depthwise: FoldedConv,
    project: FoldedConv,
    use_residual: bool,
}

impl FoldedBlock {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let y = match &self.expand {
            Some(e) => e.forward(x, None)?,
            None => x.clone(),
        };
        let y = self.depthwise.forward(&y, None)?;
        let residual = self.use_residual.then_some(x);
        self.project.forward(&y, residual)
    }
}

/// The eval-mode network with batch norm folded away.
#[derive(Debug)]
struct Folded {
    stem: FoldedConv,
    blocks: Vec<FoldedBlock>,
    head: FoldedConv,
}

impl Folded {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut y = self.stem.forward(x, None)?;
        for b in &self.blocks {
            y = b.forward(&y)?;
        }
        self.head.forward(&y, None)
    }
}

/// MobileNetV2 with torchvision's layout and parameter names.
#[derive(Debug)]
pub struct MobileNetV2 {
    stem: ConvBn,
    blocks: Vec<InvertedResidual>,
    head: ConvBn,
    classifier: Linear,
    dropout: f64,
    last_channel: usize,
    folded: Mutex<Option<Arc<Folded>>>,
}

impl MobileNetV2 {
    /// Builds the network from `vb`: a checkpoint (see [`crate::weights`]) or
    /// a `VarMap` for training from scratch (torchvision's initialization).
    pub fn new(vb: VarBuilder, cfg: &MobileNetV2Config) -> Result<Self> {
        if !(cfg.width_mult > 0.0 && cfg.width_mult.is_finite()) {
            candle_core::bail!("width_mult must be positive, got {}", cfg.width_mult);
        }
        if !(0.0..1.0).contains(&cfg.dropout) {
            candle_core::bail!("dropout must be in [0, 1), got {}", cfg.dropout);
        }
        let features = vb.pp("features");
        let mut cin = make_divisible(32.0 * cfg.width_mult, 8);
        let last_channel = make_divisible(1280.0 * cfg.width_mult.max(1.0), 8);
        let stem_names = ConvNames {
            conv: "0.0",
            bn: "0.1",
        };
        let stem = ConvBn::new(&features, stem_names, (3, cin), ConvKind::Full3x3, 2, true)?;
        let mut blocks = Vec::new();
        for (t, c, n, s) in INVERTED_RESIDUAL_SETTING {
            let cout = make_divisible(c as f64 * cfg.width_mult, 8);
            for i in 0..n {
                let stride = if i == 0 { s } else { 1 };
                let vb_block = features.pp((blocks.len() + 1).to_string());
                blocks.push(InvertedResidual::new(vb_block, cin, cout, stride, t)?);
                cin = cout;
            }
        }
        let idx = blocks.len() + 1;
        let (conv, bn) = (format!("{idx}.0"), format!("{idx}.1"));
        let head_names = ConvNames {
            conv: &conv,
            bn: &bn,
        };
        let head = ConvBn::new(
            &features,
            head_names,
            (cin, last_channel),
            ConvKind::Pointwise,
            1,
            true,
        )?;
        let classifier = linear(last_channel, cfg.num_classes, vb.pp("classifier").pp("1"))?;
        Ok(Self {
            stem,
            blocks,
            head,
            classifier,
            dropout: cfg.dropout,
            last_channel,
            folded: Mutex::new(None),
        })
    }

    /// Length of the pooled feature vector (1280 at width 1.0).
    pub fn feature_dim(&self) -> usize {
        self.last_channel
    }

    /// Globally average-pooled features (N, feature_dim) of normalized images
    /// (N, 3, H, W). `train` selects batch statistics (and updates the
    /// running ones) instead of the folded eval-mode network.
    pub fn features(&self, x: &Tensor, train: bool) -> Result<Tensor> {
        let (_, c, _, _) = x.dims4()?;
        if c != 3 {
            candle_core::bail!("MobileNetV2 expects 3 input channels, got {:?}", x.dims());
        }
        if train {
            self.invalidate_inference_cache();
            pool(&self.feature_map_train(x)?)
        } else {
            self.features_eval(x)
        }
    }

    /// Class logits (N, num_classes). Dropout is active only when `train`.
    pub fn forward(&self, x: &Tensor, train: bool) -> Result<Tensor> {
        let f = self.features(x, train)?;
        let f = if train && self.dropout > 0.0 {
            candle_nn::ops::dropout(&f, self.dropout as f32)?
        } else {
            f
        };
        self.classifier.forward(&f)
    }

    /// Drops the cached folded weights. Train-mode calls do this already;
    /// call it after changing the weights any other way (e.g. `VarMap::load`).
    pub fn invalidate_inference_cache(&self) {
        if let Ok(mut g) = self.folded.lock() {
            *g = None;
        }
    }

    fn feature_map_train(&self, x: &Tensor) -> Result<Tensor> {
        let mut y = self.stem.forward_train(x)?;
        for b in &self.blocks {
            y = b.forward_train(&y)?;
        }
        self.head.forward_train(&y)
    }

    /// Pooled eval-mode features. A batch runs one image per task, so that
    /// each image's activations stay in cache and buffers are reused; the
    /// kernels split a single image across threads themselves.
    fn features_eval(&self, x: &Tensor) -> Result<Tensor> {
        let folded = self.folded_network()?;
        let n = x.dim(0)?;
        if n == 1 {
            return pool(&folded.forward(x)?);
        }
        let rows = (0..n)
            .into_par_iter()
            .map(|i| pool(&folded.forward(&x.narrow(0, i, 1)?)?))
            .collect::<Result<Vec<_>>>()?;
        Tensor::cat(&rows, 0)
    }

    fn folded_network(&self) -> Result<Arc<Folded>> {
        let mut guard = self
            .folded
            .lock()
            .map_err(|_| candle_core::Error::Msg("MobileNetV2 fold cache poisoned".into()))?;
        if let Some(f) = guard.as_ref() {
            return Ok(f.clone());
        }
        let folded = Arc::new(Folded {
            stem: self.stem.fold()?,
            blocks: self
                .blocks
                .iter()
                .map(InvertedResidual::fold)
                .collect::<Result<_>>()?,
            head: self.head.fold()?,
        });
        *guard = Some(folded.clone());
        Ok(folded)
    }
}

/// Global average pooling: (N, C, H, W) -> (N, C).
fn pool(x: &Tensor) -> Result<Tensor> {
    x.flatten_from(2)?.mean(D::Minus1)
}

/// torch.nn.Linear with torchvision's MobileNetV2 init: N(0, 0.01), zero bias.
fn linear(cin: usize, cout: usize, vb: VarBuilder) -> Result<Linear> {
    let init = Init::Randn {
        mean: 0.0,
        stdev: 0.01,
    };
    let w = vb.get_with_hints((cout, cin), "weight", init)?;
    let b = vb.get_with_hints(cout, "bias", Init::Const(0.0))?;
    Ok(Linear::new(w, Some(b)))
}

#[cfg(test)]
mod tests {
    use super::make_divisible;

    #[test]
    fn make_divisible_matches_torchvision() {
        // Values computed with torchvision's _make_divisible.
        assert_eq!(make_divisible(32.0, 8), 32);
        assert_eq!(make_divisible(32.0 * 0.25, 8), 8);
        assert_eq!(make_divisible(16.0 * 0.25, 8), 8);
        assert_eq!(make_divisible(24.0 * 0.35, 8), 8);
        assert_eq!(make_divisible(96.0 * 0.35, 8), 32);
        assert_eq!(make_divisible(160.0 * 0.75, 8), 120);
        assert_eq!(make_divisible(24.0 * 1.4, 8), 32);
        // never rounds down by more than 10%
        assert_eq!(make_divisible(20.0, 16), 32);
    }
}
