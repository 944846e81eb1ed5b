//! Loading checkpoints into a `VarBuilder`: PyTorch `.pth`/`.pt` (the zip
//! format through candle's pickle support, or the legacy pre-1.6 format of
//! torchvision's `mobilenet_v2-b0353104.pth`) or `.safetensors`.
//!
//! The file is read eagerly and the tensors are served by a backend that
//! checks names and shapes itself, so that every load error names the file
//! and the tensor.

pub mod legacy_pth;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::error::{ModelError, Result};
use candle_core::{DType, Device, Shape, Tensor};
use candle_nn::var_builder::SimpleBackend;
use candle_nn::{Init, VarBuilder};

/// Checkpoint formats, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Pth,
    Safetensors,
}

impl Format {
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("pth") | Some("pt") => Ok(Self::Pth),
            Some("safetensors") => Ok(Self::Safetensors),
            _ => Err(ModelError::Invalid(format!(
                "weights file {}: unknown extension, expected .pth, .pt or .safetensors",
                path.display()
            ))),
        }
    }
}

/// Reads every tensor of a checkpoint, keyed by parameter name.
pub fn load_tensors(path: &Path, device: &Device) -> Result<HashMap<String, Tensor>> {
    let format = Format::from_path(path)?;
    if !path.is_file() {
        return Err(ModelError::Missing {
            what: "weights file",
            path: path.to_path_buf(),
        });
    }
    let tensors = match format {
        Format::Safetensors => {
            candle_core::safetensors::load(path, device).map_err(|e| ModelError::Unreadable {
                path: path.to_path_buf(),
                what: "not a readable safetensors file",
                source: Box::new(e),
            })?
        }
        Format::Pth => load_pth(path, device)?,
    };
    if tensors.is_empty() {
        return Err(ModelError::Corrupt {
            path: path.to_path_buf(),
            reason: "the weights file holds no tensors".into(),
        });
    }
    Ok(tensors)
}

fn load_pth(path: &Path, device: &Device) -> Result<HashMap<String, Tensor>> {
    if legacy_pth::is_legacy(path) {
        return legacy_pth::load(path, device).map_err(|source| ModelError::LegacyPth {
            path: path.to_path_buf(),
            source,
        });
    }
    let mut entries =
        candle_core::pickle::read_all_with_key(path, None).map_err(|e| ModelError::Unreadable {
            path: path.to_path_buf(),
            what: "not a readable PyTorch checkpoint (torch.save of a state_dict)",
            source: Box::new(e),
        })?;
    if entries.is_empty() {
        // Training checkpoints often wrap the weights: {"state_dict": {...}}.
        entries =
            candle_core::pickle::read_all_with_key(path, Some("state_dict")).unwrap_or_default();
    }
    entries
        .into_iter()
        .map(|(name, t)| Ok((name, t.to_device(device)?)))
        .collect()
}

/// A `VarBuilder` over the checkpoint at `path` (by extension: `.pth`/`.pt`
/// or `.safetensors`), producing f32 tensors on `device`.
pub fn var_builder(path: &Path, device: &Device) -> Result<VarBuilder<'static>> {
    let tensors = load_tensors(path, device)?;
    let backend = CheckedTensors {
        path: path.to_path_buf(),
        tensors,
    };
    Ok(VarBuilder::from_backend(
        Box::new(backend),
        DType::F32,
        device.clone(),
    ))
}

/// Tensors of one file; errors name the file and the tensor.
struct CheckedTensors {
    path: PathBuf,
    tensors: HashMap<String, Tensor>,
}

impl CheckedTensors {
    fn missing(&self, name: &str) -> candle_core::Error {
        let prefix = name.rsplit_once('.').map_or("", |(p, _)| p);
        let mut near: Vec<&str> = self
            .tensors
            .keys()
            .filter(|k| !prefix.is_empty() && k.starts_with(prefix))
            .map(String::as_str)
            .collect();
        near.sort_unstable();
        let hint = if near.is_empty() {
            format!("it holds {} tensors", self.tensors.len())
        } else {
            format!("it has {}", near.join(", "))
        };
        candle_core::Error::Msg(format!(
            "weights file {}: missing tensor `{name}` ({hint})",
            self.path.display()
        ))
    }
}

impl SimpleBackend for CheckedTensors {
    fn get(
        &self,
        s: Shape,
        name: &str,
        _: Init,
        dtype: DType,
        dev: &Device,
    ) -> candle_core::Result<Tensor> {
        let t = self.get_unchecked(name, dtype, dev)?;
        if t.shape() != &s {
            return Err(candle_core::Error::Msg(format!(
                "weights file {}: tensor `{name}` has shape {:?}, the model expects {:?} \
                 (wrong width multiplier or number of classes?)",
                self.path.display(),
                t.dims(),
                s.dims()
            )));
        }
        Ok(t)
    }

    fn get_unchecked(&self, name: &str, dtype: DType, dev: &Device) -> candle_core::Result<Tensor> {
        let t = self.tensors.get(name).ok_or_else(|| self.missing(name))?;
        t.to_dtype(dtype)?.to_device(dev)
    }

    fn contains_tensor(&self, name: &str) -> bool {
        self.tensors.contains_key(name)
    }
}
