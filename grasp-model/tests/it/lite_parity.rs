//! The candle EfficientNet-Lite against a plain PyTorch one, on a committed
//! fixture made by scripts/make_lite_fixture.py: a reduced network (width
//! 0.15, depth 0.5, stem 16, head 64, 10 classes) with random weights and
//! batch-norm statistics from real activations, some running variances
//! below TensorFlow's epsilon of 1e-3, saved in the legacy `.pth` format with
//! permuted TensorFlow-layout storages and shared, offset storages like the
//! pip-installed ImageNet files. Inputs of an odd (37x37, batch 2) and an
//! even, non-square (48x40, batch 1) size exercise SAME padding both ways.

use crate::common::{fixture, max_rel_diff};
use candle_core::{Device, Tensor};
use grasp_model::networks::{EfficientNetLite, EfficientNetLiteConfig};
use grasp_model::weights;

const TOL: f32 = 1e-4;

fn config() -> EfficientNetLiteConfig {
    EfficientNetLiteConfig {
        width: 0.15,
        depth: 0.5,
        stem_channels: 16,
        head_channels: 64,
        num_classes: Some(10),
    }
}

#[test]
fn matches_pytorch_at_odd_and_even_sizes() {
    let vb = weights::var_builder(&fixture("lite_small_legacy.pth"), &Device::Cpu).unwrap();
    let model = EfficientNetLite::new(vb, &config()).unwrap();
    let io =
        candle_core::safetensors::load(fixture("lite_small_io.safetensors"), &Device::Cpu).unwrap();
    let mut worst = 0f32;
    for tag in ["odd", "even"] {
        let x = &io[&format!("input_{tag}")];
        let features = model.features(x).unwrap();
        let d = max_rel_diff(&features, &io[&format!("features_{tag}")]);
        assert!(d < TOL, "{tag}: features differ by {d}");
        let logits = model.forward(x).unwrap();
        let e = max_rel_diff(&logits, &io[&format!("logits_{tag}")]);
        assert!(e < TOL, "{tag}: logits differ by {e}");
        worst = worst.max(d).max(e);
        // the features are not degenerate (a constant would match nothing)
        let spread = features.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let distinct = spread.iter().filter(|v| **v > 1e-3).count();
        assert!(distinct > spread.len() / 2, "{tag}: mostly zero features");
    }
    println!("max relative difference from PyTorch: {worst:.2e}");
}

#[test]
fn the_batch_path_matches_single_images() {
    let vb = weights::var_builder(&fixture("lite_small_legacy.pth"), &Device::Cpu).unwrap();
    let model = EfficientNetLite::new(vb, &config()).unwrap();
    let io =
        candle_core::safetensors::load(fixture("lite_small_io.safetensors"), &Device::Cpu).unwrap();
    let x = &io["input_odd"];
    let batch = model.features(x).unwrap();
    for i in 0..2 {
        let one = model.features(&x.narrow(0, i, 1).unwrap()).unwrap();
        let d = max_rel_diff(&one, &batch.narrow(0, i, 1).unwrap());
        assert!(d < 1e-6, "image {i}: {d}");
    }
}

/// Deterministic values in [-1, 1): a fixed input or weight, the same on
/// every run and CPU.
fn fixed(len: usize, seed: u64) -> Vec<f32> {
    let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..len)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 23) as f32 - 1.0
        })
        .collect()
}

/// Lite0's layout (the shipped network: blocks 7, 10, 14 and 15 pooled
/// beside the head) with fixed weights: convolutions scaled as their
/// He initialisation, batch norms near identity.
fn fixed_lite0() -> EfficientNetLite {
    use candle_nn::{VarBuilder, VarMap};
    let map = VarMap::new();
    let vb = VarBuilder::from_varmap(&map, candle_core::DType::F32, &Device::Cpu);
    let cfg = EfficientNetLiteConfig::variant(grasp_model::networks::LiteVariant::Lite0, None);
    EfficientNetLite::new(vb, &cfg).unwrap(); // creates the variables
    let mut vars = map
        .data()
        .lock()
        .unwrap()
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect::<Vec<_>>();
    vars.sort_by(|a, b| a.0.cmp(&b.0));
    for (i, (name, var)) in vars.iter().enumerate() {
        let dims = var.dims().to_vec();
        let n: usize = dims.iter().product();
        let v = fixed(n, i as u64);
        let values: Vec<f32> = if name.ends_with("running_var") {
            v.iter().map(|x| 1.0 + 0.5 * x).collect()
        } else if name.ends_with("weight") && dims.len() == 4 {
            let fan_in = (dims[1] * dims[2] * dims[3]) as f32;
            v.iter().map(|x| x * (6.0 / fan_in).sqrt()).collect()
        } else if name.ends_with("weight") {
            v.iter().map(|x| 1.0 + 0.1 * x).collect() // batch-norm scale
        } else {
            v.iter().map(|x| 0.1 * x).collect() // shifts and means
        };
        var.set(&Tensor::from_vec(values, dims, &Device::Cpu).unwrap())
            .unwrap();
    }
    // batch norm is folded at construction: build on the fixed variables
    let vb = VarBuilder::from_varmap(&map, candle_core::DType::F32, &Device::Cpu);
    let mut net = EfficientNetLite::new(vb, &cfg).unwrap();
    net.set_pooled_blocks(&[7, 10, 14, 15]).unwrap();
    net
}

/// The packed-weight 1x1 kernels (narrow and wide, AVX-512) against the
/// `gemm` path on the shipped network's layout, at the shipped 128 px and
/// at 100 px (maps whose pixels fill no whole tile of 64), within 1e-5.
/// Without AVX-512 both paths are `gemm`'s and agree exactly.
#[test]
fn packed_kernels_match_the_gemm_path_on_lite0() {
    let mut net = fixed_lite0();
    for (side, seed) in [(128, 7), (100, 8)] {
        let x = Tensor::from_vec(
            fixed(3 * side * side, seed),
            (1, 3, side, side),
            &Device::Cpu,
        )
        .unwrap()
        .affine(2.0, 0.0)
        .unwrap();
        net.set_packed_kernels(true);
        let packed = net.features(&x).unwrap();
        net.set_packed_kernels(false);
        let reference = net.features(&x).unwrap();
        assert_eq!(packed.dims(), [1, 1280 + 80 + 112 + 192 + 320]);
        let d = max_rel_diff(&packed, &reference);
        assert!(
            d < 1e-5,
            "{side} px: packed kernels differ from gemm's by {d}"
        );
        let values = reference.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let live = values.iter().filter(|v| v.abs() > 1e-3).count();
        assert!(live > values.len() / 2, "{side} px: mostly zero features");
        println!("{side} px: max relative difference {d:.2e}");
    }
}
