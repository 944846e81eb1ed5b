//! The candle MobileNetV2 against torchvision's, on a committed fixture made
//! by scripts/make_parity_fixture.py (width 0.1, 5 classes, random weights,
//! batch-norm statistics from real activations, a 2x3x45x45 input).

use crate::common::{fixture, max_rel_diff};
use candle_core::{Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use grasp_model::networks::{MobileNetV2, MobileNetV2Config};
use grasp_model::weights;

const TOL: f32 = 1e-4;

fn config() -> MobileNetV2Config {
    MobileNetV2Config {
        width_mult: 0.1,
        num_classes: 5,
        dropout: 0.2,
    }
}

fn expected() -> std::collections::HashMap<String, Tensor> {
    candle_core::safetensors::load(fixture("mnv2_w010_io.safetensors"), &Device::Cpu).unwrap()
}

fn check_eval(file: &str) {
    let vb = weights::var_builder(&fixture(file), &Device::Cpu).unwrap();
    let model = MobileNetV2::new(vb, &config()).unwrap();
    let io = expected();
    let x = &io["input"];
    let features = model.features(x, false).unwrap();
    assert_eq!(model.feature_dim(), 1280);
    let d = max_rel_diff(&features, &io["features"]);
    assert!(d < TOL, "{file}: features differ by {d}");
    // batch 1 takes the intra-image parallel path, batches one image per task
    let single = model.features(&x.narrow(0, 1, 1).unwrap(), false).unwrap();
    let d = max_rel_diff(&single, &io["features"].narrow(0, 1, 1).unwrap());
    assert!(d < TOL, "{file}: batch-1 features differ by {d}");
    let logits = model.forward(x, false).unwrap();
    let d = max_rel_diff(&logits, &io["logits"]);
    assert!(d < TOL, "{file}: logits differ by {d}");
}

#[test]
fn eval_matches_torchvision_from_pth() {
    check_eval("mnv2_w010.pth");
}

#[test]
fn eval_matches_torchvision_from_safetensors() {
    check_eval("mnv2_w010.safetensors");
}

#[test]
fn train_mode_matches_torchvision_and_updates_running_stats() {
    // Load into a VarMap, as training does, so the running stats are variables.
    let mut varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, candle_core::DType::F32, &Device::Cpu);
    let model = MobileNetV2::new(vb, &config()).unwrap();
    varmap.load(fixture("mnv2_w010.safetensors")).unwrap();
    model.invalidate_inference_cache();
    let io = expected();
    let x = &io["input"];
    // eval first: this caches the folded network, which the train pass must drop
    let before = model.features(x, false).unwrap();
    assert!(max_rel_diff(&before, &io["features"]) < TOL);

    let train = model.features(x, true).unwrap();
    let d = max_rel_diff(&train, &io["train_features"]);
    assert!(d < TOL, "train-mode features differ by {d}");
    let data = varmap.data().lock().unwrap();
    for stat in ["mean", "var"] {
        let got = data[&format!("features.1.conv.0.1.running_{stat}")].as_tensor();
        let d = max_rel_diff(got, &io[&format!("train_running_{stat}")]);
        assert!(d < TOL, "running_{stat} after a train pass differs by {d}");
    }
    drop(data);
    // the eval path now sees the updated statistics, so it differs from before
    let after = model.features(x, false).unwrap();
    assert!(max_rel_diff(&after, &before) > 1e-4);
}

#[test]
fn train_mode_is_differentiable_end_to_end() {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, candle_core::DType::F32, &Device::Cpu);
    let model = MobileNetV2::new(vb, &config()).unwrap();
    let x = Tensor::randn(0f32, 1.0, (2, 3, 32, 32), &Device::Cpu).unwrap();
    let loss = model
        .forward(&x, true)
        .unwrap()
        .sqr()
        .unwrap()
        .sum_all()
        .unwrap();
    let grads = loss.backward().unwrap();
    let data = varmap.data().lock().unwrap();
    for name in [
        "features.0.0.weight",
        "features.2.conv.1.0.weight", // a depthwise layer (custom op backward)
        "features.2.conv.2.weight",   // a projection
        "classifier.1.weight",
    ] {
        let g = grads.get(data[name].as_tensor()).expect(name);
        let norm = g
            .sqr()
            .unwrap()
            .sum_all()
            .unwrap()
            .to_scalar::<f32>()
            .unwrap();
        assert!(
            norm.is_finite() && norm > 0.0,
            "{name}: gradient norm {norm}"
        );
    }
}
