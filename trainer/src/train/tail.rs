//! Fine-tuned mode's two halves: the frozen blocks' activations, cached like
//! features ([`BlockActivations`]), and the trainable last blocks that turn
//! them into the head's features ([`Tail`]).

use crate::error::{ConfigError, Result};
use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use grasp_model::backbone::{Backbone, Network};
use grasp_model::extractor::FeatureExtractor;
use grasp_model::networks::{tail_pooling, BlockSpec, EfficientNetLite, LiteTail};
use grasp_model::style::ChannelStyle;
use image::RgbImage;

/// The pretrained EfficientNet-Lite of a backbone, or why there is none.
pub fn lite(bb: &Backbone) -> Result<&EfficientNetLite, ConfigError> {
    match &bb.net {
        Network::EfficientNetLite(n) => Ok(n),
        Network::MobileNetV2(_) => Err(ConfigError::invalid(
            "backbone",
            "fine-tuned mode tunes the last blocks of an EfficientNet-Lite, not MobileNetV2",
        )),
    }
}

/// Activations of the blocks before `from`, flattened to one row per frame:
/// what the feature cache stores in fine-tuned mode.
pub struct BlockActivations<'a> {
    backbone: &'a Backbone,
    from: usize,
    /// (channels, height, width) of one frame's activations.
    pub shape: (usize, usize, usize),
}

impl<'a> BlockActivations<'a> {
    /// The activations in front of the last `tuned` blocks.
    pub fn new(backbone: &'a Backbone, tuned: usize) -> Result<Self> {
        let net = lite(backbone)?;
        let from = net.block_count().checked_sub(tuned).ok_or_else(|| {
            let reason = format!(
                "fine_tune.blocks = {tuned}, but {} has {} blocks",
                backbone.info.arch.name(),
                net.block_count()
            );
            ConfigError::invalid("fine_tune.blocks", reason)
        })?;
        let side = backbone.preprocess.size as usize;
        let probe = Tensor::zeros((1, 3, side, side), DType::F32, &backbone.device)?;
        let (_, c, h, w) = net.feature_map_until(&probe, from)?.dims4()?;
        Ok(BlockActivations {
            backbone,
            from,
            shape: (c, h, w),
        })
    }

    /// The activations in front of `start`'s blocks, as [`Self::new`]
    /// found them for it (no second probe of their shape).
    pub fn before(backbone: &'a Backbone, start: &TailStart) -> Self {
        BlockActivations {
            backbone,
            from: start.from,
            shape: start.shape,
        }
    }

    pub fn first_tuned_block(&self) -> usize {
        self.from
    }
}

impl FeatureExtractor for BlockActivations<'_> {
    fn id(&self) -> String {
        // the pooled blocks change only what the tail reads from the cache
        format!(
            "{} activations before block {}",
            self.backbone.network_id(),
            self.from
        )
    }

    fn feature_dim(&self) -> usize {
        self.shape.0 * self.shape.1 * self.shape.2
    }

    fn extract(&self, images: &[RgbImage]) -> grasp_model::error::Result<Tensor> {
        let x = self.backbone.input(images)?;
        Ok(self
            .net()?
            .feature_map_until(&x, self.from)?
            .flatten_from(1)?)
    }

    /// Only the frozen blocks in front of the tuned ones.
    fn block_channels(&self) -> Vec<usize> {
        let mut channels = self.backbone.block_channels();
        channels.truncate(self.from);
        channels
    }

    fn extract_styled(
        &self,
        images: &[RgbImage],
        styles: &[Vec<ChannelStyle>],
    ) -> grasp_model::error::Result<Tensor> {
        let x = self.backbone.input(images)?;
        let map = self
            .net()?
            .styled_feature_map_until(&x, self.from, styles)?;
        Ok(map.flatten_from(1)?)
    }
}

impl BlockActivations<'_> {
    fn net(&self) -> grasp_model::error::Result<&EfficientNetLite> {
        lite(self.backbone).map_err(|e| grasp_model::error::ModelError::Invalid(e.to_string()))
    }
}

/// What a fine-tuned run starts its tail from.
#[derive(Clone)]
pub struct TailStart {
    pub from: usize,
    pub shape: (usize, usize, usize),
    pub layout: (Vec<(usize, BlockSpec)>, (usize, usize)),
    /// The pretrained folded tensors of the tuned blocks.
    pub tensors: Vec<(String, Tensor)>,
    /// The network's pooled blocks, whose outputs the tail appends.
    pub pooled_blocks: Vec<usize>,
}

impl TailStart {
    pub fn new(backbone: &Backbone, acts: &BlockActivations) -> Result<Self> {
        let net = lite(backbone)?;
        let start = TailStart {
            from: acts.from,
            shape: acts.shape,
            layout: net.tail_layout(acts.from),
            tensors: net.tail_tensors(acts.from),
            pooled_blocks: net.pooled_blocks().to_vec(),
        };
        // refused before any activation is cached, not when training starts
        tail_pooling(start.from, net.block_count(), &start.pooled_blocks)?;
        Ok(start)
    }
}

/// The trainable last blocks: their variables, initialised with the
/// pretrained tensors, and the module that runs them.
pub struct Tail {
    pub vars: VarMap,
    module: LiteTail,
    shape: (usize, usize, usize),
}

impl Tail {
    pub fn new(start: &TailStart, dev: &Device) -> Result<Self> {
        let vars = VarMap::new();
        {
            let mut data = vars.data().lock().expect("varmap");
            for (name, t) in &start.tensors {
                // a copy: training must not write into the backbone's tensors
                data.insert(name.clone(), Var::from_tensor(&t.copy()?)?);
            }
        }
        let vb = VarBuilder::from_varmap(&vars, DType::F32, dev);
        let module = LiteTail::new(&vb, &start.layout)?
            .with_pooled_blocks(start.from, &start.pooled_blocks)?;
        Ok(Tail {
            vars,
            module,
            shape: start.shape,
        })
    }

    /// The head's features `(N, D)` of cached activation rows `(N, C*H*W)`.
    pub fn forward(&self, rows: &Tensor) -> Result<Tensor> {
        let (c, h, w) = self.shape;
        let n = rows.dim(0)?;
        Ok(self.module.forward(&rows.reshape((n, c, h, w))?)?)
    }
}
