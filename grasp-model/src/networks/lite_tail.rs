//! The last blocks of EfficientNet-Lite and its head convolution as a
//! differentiable module, for fine-tuning them on cached activations of the
//! frozen blocks before them.
//!
//! Batch norm stays frozen, so every convolution is trained in its folded
//! form (weight and bias with the norm included), the form in which
//! [`EfficientNetLite::load_tail`](super::EfficientNetLite::load_tail) puts
//! the tuned tensors back into the fused inference kernels.

use super::efficientnet_lite::{head_then_blocks, BlockSpec};
use crate::ops::depthwise::{depthwise_conv, Padding};
use candle_core::{Result, Tensor};
use candle_nn::VarBuilder;

/// Activations as one row per pixel, `(N*H*W, C)`: a 1x1 convolution is
/// then a single matrix product (a batch of per-image products is several
/// times slower in candle, forward and backward).
struct Pixels {
    rows: Tensor,
    n: usize,
    h: usize,
    w: usize,
}

impl Pixels {
    fn from_nchw(x: &Tensor) -> Result<Self> {
        let (n, c, h, w) = x.dims4()?;
        let rows = x.permute((0, 2, 3, 1))?.reshape((n * h * w, c))?;
        Ok(Pixels { rows, n, h, w })
    }

    fn to_nchw(&self) -> Result<Tensor> {
        let c = self.rows.dim(1)?;
        self.rows
            .reshape((self.n, self.h, self.w, c))?
            .permute((0, 3, 1, 2))?
            .contiguous()
    }

    fn with_rows(&self, rows: Tensor) -> Self {
        Pixels { rows, ..*self }
    }

    /// Global average pooling: (N, C).
    fn pool(&self) -> Result<Tensor> {
        let c = self.rows.dim(1)?;
        self.rows.reshape((self.n, self.h * self.w, c))?.mean(1)
    }
}

/// A folded convolution's trainable weight and bias.
struct Conv {
    weight: Tensor,
    bias: Tensor,
}

impl Conv {
    fn new(vb: &VarBuilder, name: &str, shape: [usize; 4]) -> Result<Self> {
        Ok(Conv {
            weight: vb.get(shape.to_vec(), &format!("{name}.weight"))?,
            bias: vb.get(shape[0], &format!("{name}.bias"))?,
        })
    }

    /// 1x1 convolution plus bias of pixel rows.
    fn pointwise(&self, x: &Pixels) -> Result<Pixels> {
        let (cout, cin) = (self.weight.dim(0)?, self.weight.dim(1)?);
        let w = self.weight.reshape((cout, cin))?;
        let y = x
            .rows
            .matmul(&w.t()?)?
            .broadcast_add(&self.bias.unsqueeze(0)?)?;
        Ok(x.with_rows(y))
    }

    /// Depthwise convolution ("SAME") plus bias of pixel rows.
    fn depthwise(&self, x: &Pixels, stride: usize) -> Result<Pixels> {
        let y = depthwise_conv(&x.to_nchw()?, &self.weight, stride, Padding::Same)?;
        let y = Pixels::from_nchw(&y)?;
        let rows = y.rows.broadcast_add(&self.bias.unsqueeze(0)?)?;
        Ok(y.with_rows(rows))
    }
}

struct TailBlock {
    spec: BlockSpec,
    expand: Option<Conv>,
    depthwise: Conv,
    project: Conv,
}

impl TailBlock {
    fn new(vb: &VarBuilder, index: usize, spec: BlockSpec) -> Result<Self> {
        let (cin, hidden, k) = (spec.cin, spec.hidden(), spec.kernel);
        let name = |layer: &str| format!("_blocks.{index}.{layer}");
        let expand = (spec.expand != 1)
            .then(|| Conv::new(vb, &name("_expand_conv"), [hidden, cin, 1, 1]))
            .transpose()?;
        Ok(TailBlock {
            spec,
            expand,
            depthwise: Conv::new(vb, &name("_depthwise_conv"), [hidden, 1, k, k])?,
            project: Conv::new(vb, &name("_project_conv"), [spec.cout, hidden, 1, 1])?,
        })
    }

    fn forward(&self, x: &Pixels) -> Result<Pixels> {
        let y = match &self.expand {
            Some(e) => relu6(e.pointwise(x)?)?,
            None => x.with_rows(x.rows.clone()),
        };
        let y = relu6(self.depthwise.depthwise(&y, self.spec.stride)?)?;
        let y = self.project.pointwise(&y)?;
        if self.spec.residual() {
            let rows = (&y.rows + &x.rows)?;
            Ok(y.with_rows(rows))
        } else {
            Ok(y)
        }
    }
}

/// Blocks `from..` of an EfficientNet-Lite and its head convolution, with
/// global average pooling: activations (N, C, H, W) of block `from - 1` in,
/// pooled features (N, 1280) out, followed by the pooled outputs of the
/// network's pooled blocks when it has some (see
/// [`EfficientNetLite::set_pooled_blocks`](super::EfficientNetLite::set_pooled_blocks)).
pub struct LiteTail {
    blocks: Vec<TailBlock>,
    head: Conv,
    /// Whether the input (block `from - 1`'s output) is a pooled block.
    pool_input: bool,
    /// Positions in `blocks` of the pooled blocks.
    pooled: Vec<usize>,
}

impl LiteTail {
    /// Reads the folded tensors named as
    /// [`EfficientNetLite::tail_tensors`](super::EfficientNetLite::tail_tensors)
    /// names them from `vb`; `layout` is
    /// [`EfficientNetLite::tail_layout`](super::EfficientNetLite::tail_layout).
    pub fn new(
        vb: &VarBuilder,
        layout: &(Vec<(usize, BlockSpec)>, (usize, usize)),
    ) -> Result<Self> {
        let (specs, (head_out, head_in)) = layout;
        let blocks = specs
            .iter()
            .map(|(i, spec)| TailBlock::new(vb, *i, *spec))
            .collect::<Result<Vec<_>>>()?;
        let head = Conv::new(vb, "_conv_head", [*head_out, *head_in, 1, 1])?;
        Ok(LiteTail {
            blocks,
            head,
            pool_input: false,
            pooled: Vec::new(),
        })
    }

    /// Appends the pooled outputs of the network's `pooled_blocks` to the
    /// features, as the inference network does (see [`tail_pooling`]).
    pub fn with_pooled_blocks(mut self, from: usize, pooled_blocks: &[usize]) -> Result<Self> {
        (self.pool_input, self.pooled) =
            tail_pooling(from, from + self.blocks.len(), pooled_blocks)?;
        Ok(self)
    }

    /// Pooled features (N, D) of block activations (N, C, H, W).
    pub fn forward(&self, map: &Tensor) -> Result<Tensor> {
        let mut y = Pixels::from_nchw(map)?;
        let mut extra = Vec::with_capacity(self.pooled.len() + 1);
        if self.pool_input {
            extra.push(y.pool()?);
        }
        for (k, b) in self.blocks.iter().enumerate() {
            y = b.forward(&y)?;
            if self.pooled.contains(&k) {
                extra.push(y.pool()?);
            }
        }
        head_then_blocks(relu6(self.head.pointwise(&y)?)?.pool()?, extra)
    }
}

/// Where a tail from block `from` of a network of `count` blocks finds the
/// pooled blocks: whether its input (block `from - 1`) is one, and the
/// positions of the others among its own blocks. A pooled block before
/// its input is not in the activation cache, and is refused.
pub fn tail_pooling(
    from: usize,
    count: usize,
    pooled_blocks: &[usize],
) -> Result<(bool, Vec<usize>)> {
    super::efficientnet_lite::check_pooled_blocks(pooled_blocks, count)?;
    let mut pool_input = false;
    let mut pooled = Vec::new();
    for &b in pooled_blocks {
        if b + 1 == from {
            pool_input = true;
        } else if b >= from {
            pooled.push(b - from);
        } else {
            candle_core::bail!(
                "pooled block {b} lies before the tuned blocks' input (block {}): tune more \
                 blocks or pool later ones",
                from.saturating_sub(1)
            );
        }
    }
    Ok((pool_input, pooled))
}

/// min(max(x, 0), 6) as relu(x) - relu(x - 6): candle's clamp goes through
/// broadcast comparisons and costs six times as much, with its gradient.
fn relu6(x: Pixels) -> Result<Pixels> {
    let rows = (x.rows.relu()? - x.rows.affine(1.0, -6.0)?.relu()?)?;
    Ok(x.with_rows(rows))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::networks::{EfficientNetLite, EfficientNetLiteConfig, LiteVariant};
    use crate::ops::depthwise::depthwise_conv_bias_act;
    use crate::test_util::max_diff;
    use candle_core::{DType, Device, Var};
    use candle_nn::VarMap;

    /// Reference depthwise convolution of `x` (N, C, H, W) with `weight` (C, 1, K, K),
    /// TensorFlow "SAME" padding, any stride: the stride-1 result over the
    /// padded input as a sum of K x K shifted views, each scaled per channel,
    /// then every `stride`-th row and column of it: candle operations only,
    /// so its gradients are candle's own.
    fn depthwise_same(x: &Tensor, weight: &Tensor, stride: usize) -> Result<Tensor> {
        let (_, c, h, w) = x.dims4()?;
        let (wc, _, k, k2) = weight.dims4()?;
        if wc != c || k != k2 {
            candle_core::bail!(
                "depthwise weight {:?} does not fit input {:?}",
                weight.dims(),
                x.dims()
            );
        }
        let axis = |size: usize| -> Result<(usize, usize, usize)> {
            let (out, before) = Padding::Same
                .resolve(size, k, stride)
                .ok_or_else(|| candle_core::Error::Msg(format!("kernel {k} on size {size}")))?;
            let span = (out - 1) * stride + 1; // stride-1 outputs that cover them
            let after = (span + k - 1).saturating_sub(size + before);
            Ok((out, before, after))
        };
        let ((oh, top, bottom), (ow, left, right)) = (axis(h)?, axis(w)?);
        let padded = x
            .pad_with_zeros(2, top, bottom)?
            .pad_with_zeros(3, left, right)?;
        let (sh, sw) = ((oh - 1) * stride + 1, (ow - 1) * stride + 1);
        let mut acc: Option<Tensor> = None;
        for ky in 0..k {
            for kx in 0..k {
                let tap = weight
                    .narrow(2, ky, 1)?
                    .narrow(3, kx, 1)?
                    .reshape((1, c, 1, 1))?;
                let term = padded
                    .narrow(2, ky, sh)?
                    .narrow(3, kx, sw)?
                    .broadcast_mul(&tap)?;
                acc = Some(match acc {
                    None => term,
                    Some(a) => (a + term)?,
                });
            }
        }
        let y = acc.expect("k >= 1");
        if stride == 1 {
            return Ok(y);
        }
        let pick = |n: usize| {
            let idx: Vec<u32> = (0..n).map(|i| (i * stride) as u32).collect();
            Tensor::from_vec(idx, n, x.device())
        };
        y.index_select(&pick(oh)?, 2)?.index_select(&pick(ow)?, 3)
    }

    #[test]
    fn depthwise_gradients_match_the_shifted_reference() {
        let dev = Device::Cpu;
        for (k, stride, size) in [(5, 2, 8), (5, 1, 4), (3, 1, 4), (3, 2, 7)] {
            let x = Var::from_tensor(&Tensor::randn(0f32, 1., (2, 6, size, size), &dev).unwrap())
                .unwrap();
            let w =
                Var::from_tensor(&Tensor::randn(0f32, 1., (6, 1, k, k), &dev).unwrap()).unwrap();
            // a non-uniform output gradient: weight the outputs
            let grads = |y: Tensor| {
                let mask = Tensor::arange(0f32, y.elem_count() as f32, &dev)
                    .unwrap()
                    .reshape(y.shape())
                    .unwrap()
                    .sin()
                    .unwrap();
                let g = (y * mask).unwrap().sum_all().unwrap().backward().unwrap();
                let get = |v: &Var| g.get(v.as_tensor()).unwrap().clone();
                (get(&x), get(&w))
            };
            let (dx, dw) = grads(depthwise_conv(&x, &w, stride, Padding::Same).unwrap());
            let (rx, rw) = grads(depthwise_same(&x, &w, stride).unwrap());
            assert!(
                rel_diff(&dx, &rx) < 1e-5,
                "input gradient, k {k} stride {stride}"
            );
            assert!(
                rel_diff(&dw, &rw) < 1e-5,
                "weight gradient, k {k} stride {stride}"
            );
        }
    }

    #[test]
    fn shifted_depthwise_matches_the_inference_kernel() {
        let dev = Device::Cpu;
        for (k, stride, size) in [(5, 2, 8), (5, 1, 4), (3, 1, 4), (3, 2, 7), (5, 2, 1)] {
            let x = Tensor::randn(0f32, 1., (2, 6, size, size), &dev).unwrap();
            let w = Tensor::randn(0f32, 1., (6, 1, k, k), &dev).unwrap();
            let zero = Tensor::zeros(6, DType::F32, &dev).unwrap();
            let fused = depthwise_conv_bias_act(&x, &w, &zero, stride, Padding::Same, false);
            let shifted = depthwise_same(&x, &w, stride).unwrap();
            let fused = fused.unwrap();
            assert_eq!(
                shifted.dims(),
                fused.dims(),
                "k {k} stride {stride} size {size}"
            );
            assert!(rel_diff(&shifted, &fused) < 1e-5, "k {k} stride {stride}");
        }
    }

    /// A narrow Lite0 with random convolutions scaled by their fan-in, so
    /// that activations keep their size through the blocks (the default
    /// initialisation lets them vanish, and a comparison of zeros passes).
    fn small_lite() -> (EfficientNetLite, VarMap) {
        let vm = VarMap::new();
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu);
        let mut cfg = EfficientNetLiteConfig::variant(LiteVariant::Lite0, None);
        cfg.width = 0.25;
        cfg.head_channels = 64;
        EfficientNetLite::new(vb.clone(), &cfg).unwrap();
        for (name, var) in vm.data().lock().unwrap().iter() {
            if let [_, cin, kh, kw] = var.dims() {
                let std = (2.0 / (cin * kh * kw) as f64).sqrt();
                let w = Tensor::randn(0f32, std as f32, var.shape(), &Device::Cpu).unwrap();
                var.set(&w).unwrap();
            } else if name.ends_with(".bias") {
                let b = Tensor::randn(0f32, 0.1, var.shape(), &Device::Cpu).unwrap();
                var.set(&b).unwrap();
            }
        }
        let net = EfficientNetLite::new(vb, &cfg).unwrap();
        (net, vm)
    }

    /// Largest difference relative to the largest magnitude of `b`, which
    /// must not be negligible.
    fn rel_diff(a: &Tensor, b: &Tensor) -> f32 {
        let scale = max_diff(b, &b.zeros_like().unwrap());
        assert!(scale > 0.1, "activations vanished ({scale})");
        max_diff(a, b) / scale
    }

    fn tail_varmap(tensors: &[(String, Tensor)]) -> VarMap {
        let vm = VarMap::new();
        {
            let mut data = vm.data().lock().unwrap();
            for (name, t) in tensors {
                data.insert(name.clone(), Var::from_tensor(t).unwrap());
            }
        }
        vm
    }

    #[test]
    fn the_tail_continues_the_network_and_loads_back() {
        let dev = Device::Cpu;
        let (mut net, _) = small_lite();
        let x = Tensor::randn(0f32, 1., (3, 3, 128, 128), &dev).unwrap();
        let from = 11;
        let map = net.feature_map_until(&x, from).unwrap();
        assert_eq!(map.dims()[2..], [8, 8]);
        let layout = net.tail_layout(from);
        assert_eq!(layout.0.len(), 5);
        let vm = tail_varmap(&net.tail_tensors(from));
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &dev);
        let tail = LiteTail::new(&vb, &layout).unwrap();
        let whole = net.features(&x).unwrap();
        let tuned = tail.forward(&map).unwrap();
        assert!(rel_diff(&tuned, &whole) < 1e-5);

        // changed tail tensors change the fused network the same way
        for var in vm.all_vars() {
            let scaled = (var.as_tensor() * 1.1).unwrap();
            var.set(&scaled).unwrap();
        }
        let changed = tail.forward(&map).unwrap();
        assert!(
            rel_diff(&changed, &whole) > 1e-2,
            "the tail must depend on its vars"
        );
        net.load_tail(&vb, from).unwrap();
        assert!(rel_diff(&net.features(&x).unwrap(), &changed) < 1e-5);
        // ... and leave the blocks before it alone
        assert!(max_diff(&net.feature_map_until(&x, from).unwrap(), &map) == 0.0);
    }

    /// The mean over pixels of `map` (N, C, H, W): (N, C).
    fn mean_pool(map: &Tensor) -> Tensor {
        map.flatten_from(2).unwrap().mean(2).unwrap()
    }

    #[test]
    fn pooled_blocks_follow_the_head_in_the_network_and_in_the_tail() {
        let dev = Device::Cpu;
        let (mut net, _) = small_lite();
        let x = Tensor::randn(0f32, 1., (2, 3, 96, 96), &dev).unwrap();
        let head = net.features(&x).unwrap();
        let pooled = [7, 10, 14, 15];
        net.set_pooled_blocks(&pooled).unwrap();
        let features = net.features(&x).unwrap();
        assert_eq!(features.dims(), [2, net.feature_dim()]);

        // the head's features, then each block's output averaged over pixels
        let mut expected = vec![head];
        for b in pooled {
            expected.push(mean_pool(&net.feature_map_until(&x, b + 1).unwrap()));
        }
        let expected = Tensor::cat(&expected, 1).unwrap();
        assert!(rel_diff(&features, &expected) < 1e-5);

        // a tail from block 8 pools its input (block 7) and three of its blocks
        let from = 8;
        let vm = tail_varmap(&net.tail_tensors(from));
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &dev);
        let tail = LiteTail::new(&vb, &net.tail_layout(from))
            .unwrap()
            .with_pooled_blocks(from, &pooled)
            .unwrap();
        let map = net.feature_map_until(&x, from).unwrap();
        assert!(rel_diff(&tail.forward(&map).unwrap(), &features) < 1e-5);

        // a pooled block before the tail's input is not in its cache
        let late = LiteTail::new(&vb, &net.tail_layout(from)).unwrap();
        let err = late.with_pooled_blocks(from, &[6, 10]).err().unwrap();
        assert!(err.to_string().contains("pooled block 6"), "{err}");
    }

    #[test]
    fn pooled_blocks_must_exist_and_increase() {
        let (mut net, _) = small_lite();
        for bad in [&[16][..], &[10, 7], &[7, 7]] {
            assert!(net.set_pooled_blocks(bad).is_err(), "{bad:?}");
        }
        assert!(net.pooled_blocks().is_empty());
        net.set_pooled_blocks(&[0, 15]).unwrap();
        assert_eq!(net.pooled_blocks(), [0, 15]);
    }

    #[test]
    fn every_tail_tensor_gets_a_gradient() {
        let dev = Device::Cpu;
        let (net, _) = small_lite();
        let x = Tensor::randn(0f32, 1., (2, 3, 64, 64), &dev).unwrap();
        let map = net.feature_map_until(&x, 11).unwrap();
        let vm = tail_varmap(&net.tail_tensors(11));
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &dev);
        let tail = LiteTail::new(&vb, &net.tail_layout(11)).unwrap();
        let loss = tail
            .forward(&map)
            .unwrap()
            .sqr()
            .unwrap()
            .sum_all()
            .unwrap();
        let grads = loss.backward().unwrap();
        let data = vm.data().lock().unwrap();
        for (name, var) in data.iter() {
            let g = grads.get(var.as_tensor());
            assert!(g.is_some(), "no gradient for {name}");
        }
    }

    #[test]
    fn a_tail_from_the_last_block_is_the_head_alone() {
        let dev = Device::Cpu;
        let (net, _) = small_lite();
        let x = Tensor::randn(0f32, 1., (1, 3, 32, 32), &dev).unwrap();
        let n = net.block_count();
        let vm = tail_varmap(&net.tail_tensors(n));
        assert_eq!(vm.all_vars().len(), 2);
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &dev);
        let tail = LiteTail::new(&vb, &net.tail_layout(n)).unwrap();
        let map = net.feature_map_until(&x, n).unwrap();
        assert!(rel_diff(&tail.forward(&map).unwrap(), &net.features(&x).unwrap()) < 1e-5);
        assert!(net.feature_map_until(&x, n + 1).is_err());
    }
}
