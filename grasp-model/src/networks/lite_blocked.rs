//! EfficientNet-Lite's inference on channel-blocked maps
//! ([`crate::ops::blocked`]): the pooled features of one image, the stem,
//! blocks and head run on weights packed once from the network's folded
//! ones. [`super::EfficientNetLite`] builds it on first use on AVX-512 CPUs
//! and runs its features through it; it gives the NCHW path's features to
//! the bit up to the sign of zero (`tests/it/lite_parity.rs`).

use crate::ops::blocked::{BlockedMap, DepthwiseWeights, PointwiseWeights, StemWeights};
use crate::ops::cpu::with_f32;
use crate::ops::depthwise::Padding;
use candle_core::{Result, Tensor};

/// The network's layers, packed.
#[derive(Debug)]
pub(super) struct BlockedLite {
    stem: StemWeights,
    blocks: Vec<Block>,
    head: PointwiseWeights,
}

#[derive(Debug)]
struct Block {
    expand: Option<PointwiseWeights>,
    depthwise: DepthwiseWeights,
    project: PointwiseWeights,
    residual: bool,
}

/// A folded layer's weight and bias as plain vectors.
pub(super) struct Layer {
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
}

impl Layer {
    pub fn of(weight: &Tensor, bias: &Tensor) -> Result<Self> {
        Ok(Layer {
            weight: weight.flatten_all()?.to_vec1()?,
            bias: bias.to_vec1()?,
        })
    }
}

/// One MBConv block's folded layers and geometry.
pub(super) struct BlockLayers {
    pub spec: super::BlockSpec,
    pub expand: Option<Layer>,
    pub depthwise: Layer,
    pub project: Layer,
}

impl BlockedLite {
    /// Packs the stem (3x3, stride 2, `stem_channels` outputs), the blocks
    /// and the head (`head_channels` x the last block's outputs).
    pub fn new(stem: Layer, blocks: Vec<BlockLayers>, head: Layer) -> Self {
        let stem_c = stem.bias.len();
        let stem = StemWeights::new(&stem.weight, &stem.bias, (stem_c, 3, 3), 2, Padding::Same);
        let blocks = blocks.into_iter().map(Block::new).collect::<Vec<_>>();
        let last = blocks.last().map_or(stem_c, |b| b.project.cout());
        let head = PointwiseWeights::new(&head.weight, &head.bias, head.bias.len(), last);
        let mut net = BlockedLite { stem, blocks, head };
        net.gather();
        net
    }

    /// All the packed layers in one region, in the order a frame reads them.
    fn gather(&mut self) {
        let mut parts = Vec::new();
        parts.extend(self.stem.packed_mut());
        for b in &mut self.blocks {
            if let Some(e) = &mut b.expand {
                parts.extend(e.packed_mut());
            }
            parts.extend(b.depthwise.packed_mut());
            parts.extend(b.project.packed_mut());
        }
        parts.extend(self.head.packed_mut());
        crate::ops::blocked::gather(parts);
    }

    /// The pooled head activations, then the pooled outputs of `pooled`
    /// blocks, of one normalized image `x` (1, 3, H, W): a (1, D) row.
    pub fn features(&self, x: &Tensor, pooled: &[usize]) -> Result<Tensor> {
        // The whole image on one of the pool's threads (the classifier's
        // frame already is): its ~50 layers then split their jobs from
        // inside the pool, instead of each handing its jobs over from
        // outside and waking this thread at the end (~0.1 ms a layer).
        rayon::scope(|_| self.features_in_pool(x, pooled))
    }

    fn features_in_pool(&self, x: &Tensor, pooled: &[usize]) -> Result<Tensor> {
        let (_, _, h, w) = x.dims4()?;
        let stem = |image: &[f32]| self.stem.run(image, h, w);
        let mut y =
            with_f32("EfficientNet-Lite", x, "image", stem)?.ok_or_else(|| too_small(h, w))?;
        let mut parts = Vec::with_capacity(pooled.len());
        for (i, b) in self.blocks.iter().enumerate() {
            y = b.forward(&y).ok_or_else(|| too_small(h, w))?;
            if pooled.contains(&i) {
                parts.push(y.mean_pool());
            }
        }
        let mut row = self.head.run(&y, None, true).mean_pool();
        for p in parts {
            row.extend(p);
        }
        let d = row.len();
        Tensor::from_vec(row, (1, d), x.device())
    }
}

fn too_small(h: usize, w: usize) -> candle_core::Error {
    candle_core::Error::Msg(format!("EfficientNet-Lite: a {h}x{w} image is too small"))
}

impl Block {
    fn new(l: BlockLayers) -> Self {
        let s = l.spec;
        let hidden = s.hidden();
        let expand = l
            .expand
            .map(|e| PointwiseWeights::new(&e.weight, &e.bias, hidden, s.cin));
        let (dw, k) = (&l.depthwise, s.kernel);
        let depthwise =
            DepthwiseWeights::new(&dw.weight, &dw.bias, hidden, k, s.stride, Padding::Same);
        let project = PointwiseWeights::new(&l.project.weight, &l.project.bias, s.cout, hidden);
        Block {
            expand,
            depthwise,
            project,
            residual: s.residual(),
        }
    }

    /// `None` when the map is too small for the depthwise kernel (never
    /// with SAME padding).
    fn forward(&self, x: &BlockedMap) -> Option<BlockedMap> {
        let expanded;
        let hidden = match &self.expand {
            Some(e) => {
                expanded = e.run(x, None, true);
                &expanded
            }
            None => x,
        };
        let y = self.depthwise.run(hidden, true)?;
        Some(self.project.run(&y, self.residual.then_some(x), false))
    }
}
