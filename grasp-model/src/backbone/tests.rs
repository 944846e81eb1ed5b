//! Unit tests of `backbone`.

use super::*;
use candle_nn::VarMap;

fn backbone(arch: Architecture, sha: &str, pre: Preprocess) -> Backbone {
    let vm = VarMap::new();
    let vb = VarBuilder::from_varmap(&vm, candle_core::DType::F32, &Device::Cpu);
    let mut info = BackboneInfo::generated(arch.id());
    info.arch = arch;
    info.width_mult = 0.1;
    info.weights_sha256 = Some(sha.to_string());
    Backbone::from_vb(info, pre, vb, &Device::Cpu).unwrap()
}

#[test]
fn feature_cache_keys_differ_by_architecture_weights_and_preprocessing() {
    let mnv2 = Architecture::MobileNetV2;
    let lite = Architecture::EfficientNetLite0;
    let ids = [
        backbone(mnv2, "a", mnv2.preprocess(224)).id(),
        backbone(mnv2, "b", mnv2.preprocess(224)).id(),
        backbone(mnv2, "a", mnv2.preprocess(160)).id(),
        backbone(mnv2, "a", lite.preprocess(224)).id(),
        backbone(lite, "a", lite.preprocess(224)).id(),
        backbone(lite, "a", mnv2.preprocess(224)).id(),
    ];
    for (i, a) in ids.iter().enumerate() {
        for b in &ids[i + 1..] {
            assert_ne!(a, b);
        }
    }
    // MobileNetV2's keys are those from before EfficientNet-Lite
    assert!(!ids[0].contains("architecture") && !ids[0].contains("resize"));
    assert!(ids[4].contains("efficientnet-lite0") && ids[4].contains("bicubic"));
}

#[test]
fn pooled_blocks_key_the_features_but_not_the_activations() {
    let lite = Architecture::EfficientNetLite0;
    let plain = backbone(lite, "a", lite.preprocess(64));
    let mut info = plain.info.clone();
    info.pooled_blocks = vec![7, 15];
    let vb = VarBuilder::from_varmap(&VarMap::new(), candle_core::DType::F32, &Device::Cpu);
    let pooled = Backbone::from_vb(info.clone(), lite.preprocess(64), vb, &Device::Cpu).unwrap();
    assert_ne!(plain.id(), pooled.id());
    assert_eq!(plain.network_id(), pooled.network_id());
    assert!(pooled.feature_dim() > plain.feature_dim());
    assert!(pooled.info.describe().contains("blocks [7, 15] pooled too"));

    // MobileNetV2 has no pooled blocks; a Lite0 has no block 16
    for (arch, blocks) in [(Architecture::MobileNetV2, vec![7]), (lite, vec![16])] {
        let mut bad = info.clone();
        bad.arch = arch;
        bad.pooled_blocks = blocks;
        let vb = VarBuilder::from_varmap(&VarMap::new(), candle_core::DType::F32, &Device::Cpu);
        let err = Backbone::from_vb(bad, lite.preprocess(64), vb, &Device::Cpu).err();
        assert!(
            err.is_some_and(|e| e.to_string().contains("pooled block")),
            "{arch:?}"
        );
    }
}
