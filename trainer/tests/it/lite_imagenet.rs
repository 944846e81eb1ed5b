//! The real EfficientNet-Lite0 ImageNet weights, pip-installed into the venv
//! by scripts/setup.sh, classify photographs shipped by scikit-image (the
//! `dev` extra) as PyTorch does: the expected classes were checked with the
//! PyTorch reference (`scripts/make_lite_fixture.py --imagenet`, whose top-1
//! is given per image below).
//!
//! Needs the venv. Without it the test is skipped with a message, unless
//! GRASP_REQUIRE_BLENDER=1 (set by scripts/test.sh), under which a missing
//! venv, weights file or photograph is a failure.

use std::path::PathBuf;

use candle_core::{Device, D};
use grasp_model::backbone::{Architecture, Backbone, BackboneInfo};

/// (photograph, acceptable ImageNet classes, PyTorch reference top-1).
const CASES: [(&str, &[u32], &str); 4] = [
    // tabby 281, tiger cat 282, Egyptian cat 285
    ("chelsea.png", &[281, 282, 285], "285 Egyptian cat, p 0.77"),
    // espresso 967, cup 968
    ("coffee.png", &[967, 968], "967 espresso, p 0.90"),
    // moped 665, motor scooter 670 (ImageNet has no motorcycle)
    ("motorcycle_left.png", &[665, 670], "665 moped, p 0.47"),
    // the cameraman's tripod 872 (a grey photograph)
    ("camera.png", &[872], "872 tripod, p 0.95"),
];

fn arch_default() -> Architecture {
    Architecture::EfficientNetLite0
}

/// The weights file and scikit-image's data folder, or why not.
fn prerequisites() -> Result<(PathBuf, PathBuf), String> {
    let venv = grasp_support::venv::venv_dir();
    let site = grasp_support::venv::site_packages(&venv).map_err(|e| e.to_string())?;
    let weights = grasp_model::backbone::venv_weights(grasp_model::networks::LiteVariant::Lite0)
        .map_err(|e| format!("{e:#}"))?;
    let data = site.join("skimage").join("data");
    if !data.join(CASES[0].0).is_file() {
        return Err(format!(
            "scikit-image's photographs are missing from {} (the `dev` extra); run \
             scripts/setup.sh",
            data.display()
        ));
    }
    Ok((weights, data))
}

/// [`prerequisites`], or `None` when `test` is skipped (it fails instead
/// under GRASP_REQUIRE_BLENDER=1).
fn prerequisites_or_skip(test: &str) -> Option<(PathBuf, PathBuf)> {
    use grasp_test_support::prerequisite::{check, REQUIRE_BLENDER_ENV};
    match prerequisites() {
        Ok(found) => Some(found),
        Err(why) => {
            check(test, REQUIRE_BLENDER_ENV, Some(why));
            None
        }
    }
}

#[test]
fn lite0_classifies_photographs_like_pytorch() {
    let Some((weights, data)) = prerequisites_or_skip("lite0_classifies_photographs_like_pytorch")
    else {
        return;
    };
    assert_eq!(
        trainer::plan::detect_architecture(&weights).unwrap(),
        Architecture::EfficientNetLite0
    );
    // frozen training with no weights given uses this file
    let (info, pre) =
        trainer::plan::frozen_backbone(&trainer::config::TrainConfig::default()).unwrap();
    assert_eq!(info.weights_path.as_deref(), Some(weights.as_path()));
    assert_eq!(
        (info.arch, pre),
        (arch_default(), arch_default().preprocess(224))
    );
    let arch = Architecture::EfficientNetLite0;
    let info = BackboneInfo::pretrained(&weights, arch, 1.0).unwrap();
    let bb = Backbone::load_pretrained(&info, arch.preprocess(224), &Device::Cpu).unwrap();
    let mut wrong = Vec::new();
    for (name, expected, reference) in CASES {
        let path = data.join(name);
        let img = image::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .to_rgb8();
        let logits = bb.net.logits(&bb.input(&[img]).unwrap()).unwrap();
        let probs = candle_nn::ops::softmax(&logits, D::Minus1).unwrap();
        let top = probs.argmax(D::Minus1).unwrap().to_vec1::<u32>().unwrap()[0];
        let p = probs.to_vec2::<f32>().unwrap()[0][top as usize];
        println!("{name}: top-1 {top} (p {p:.2}); PyTorch: {reference}");
        if !expected.contains(&top) {
            wrong.push(format!("{name}: {top}, expected one of {expected:?}"));
        }
    }
    assert!(wrong.is_empty(), "wrong top-1: {wrong:?}");
}

/// Lite1 and Lite2 come from the optional `backbones` extra: checked when
/// installed (detection from the file, and the first two photographs at
/// their native input sizes), skipped otherwise even under the test command
/// (the venv itself is required there).
#[test]
fn larger_variants_when_installed() {
    let Some((_, data)) = prerequisites_or_skip("larger_variants_when_installed") else {
        return;
    };
    for variant in [
        grasp_model::networks::LiteVariant::Lite1,
        grasp_model::networks::LiteVariant::Lite2,
    ] {
        let Ok(weights) = grasp_model::backbone::venv_weights(variant) else {
            // optional even under the test command
            eprintln!(
                "SKIPPED: larger_variants_when_installed: {} is not installed (the optional \
                 `backbones` extra)",
                variant.name()
            );
            continue;
        };
        let arch = Architecture::from_lite(variant);
        assert_eq!(trainer::plan::detect_architecture(&weights).unwrap(), arch);
        let info = BackboneInfo::pretrained(&weights, arch, 1.0).unwrap();
        let pre = arch.preprocess(arch.native_input_size());
        let bb = Backbone::load_pretrained(&info, pre, &Device::Cpu).unwrap();
        for (name, expected, _) in &CASES[..2] {
            let img = image::open(data.join(name)).unwrap().to_rgb8();
            let logits = bb.net.logits(&bb.input(&[img]).unwrap()).unwrap();
            let top = logits.argmax(D::Minus1).unwrap().to_vec1::<u32>().unwrap()[0];
            println!("{} {name}: top-1 {top}", variant.name());
            assert!(expected.contains(&top), "{} {name}: {top}", variant.name());
        }
    }
}
