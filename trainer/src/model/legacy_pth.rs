//! Reader for PyTorch's legacy (pre-1.6, non-zip) `torch.save` format, in
//! which torchvision's older checkpoints such as `mobilenet_v2-b0353104.pth`
//! are stored. candle reads only the zip format.
//!
//! The legacy stream is: a pickled magic number, a pickled protocol version,
//! pickled system info, the pickled object (storages as persistent ids
//! `('storage', type, key, location, size, view)`), the pickled list of
//! storage keys, then per key a little-endian u64 element count followed by
//! the raw little-endian data.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use anyhow::{bail, Context};
use candle_core::pickle::{Object, Stack, TensorInfo};
use candle_core::{Device, Tensor};

/// PROTO 2, LONG1 of 10 bytes holding 0x1950a86a20f9469cfc6c, STOP.
const MAGIC: [u8; 15] = [
    0x80, 0x02, 0x8a, 0x0a, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19, 0x2e,
];

/// True if the file starts like a legacy `torch.save` stream.
pub fn is_legacy(path: &Path) -> bool {
    let mut head = [0u8; MAGIC.len()];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head == MAGIC
}

fn read_pickle<R: BufRead>(r: &mut R) -> anyhow::Result<Object> {
    let mut stack = Stack::empty();
    stack.read_loop(r)?;
    Ok(stack.finalize()?)
}

/// Reads every tensor of a legacy checkpoint holding a state dict (or a
/// dict with a `state_dict` entry).
pub fn load(path: &Path, device: &Device) -> anyhow::Result<HashMap<String, Tensor>> {
    let file = std::fs::File::open(path)?;
    let mut r = BufReader::new(file);
    let mut magic = [0u8; MAGIC.len()];
    r.read_exact(&mut magic)?;
    if magic != MAGIC {
        bail!("not a legacy PyTorch checkpoint (bad magic number)");
    }
    read_pickle(&mut r).context("protocol version")?;
    read_pickle(&mut r).context("system info")?;
    let infos = tensor_infos(read_pickle(&mut r).context("state dict")?)?;
    let keys = match read_pickle(&mut r).context("storage keys")? {
        Object::List(keys) => keys,
        other => bail!("storage keys: expected a list, got {other:?}"),
    };
    let mut storages = HashMap::new();
    for key in keys {
        let key = key
            .unicode()
            .map_err(|o| anyhow::anyhow!("storage key {o:?}"))?;
        let mut count = [0u8; 8];
        r.read_exact(&mut count)
            .with_context(|| format!("storage {key}: truncated file"))?;
        let count = u64::from_le_bytes(count) as usize;
        let elem = infos
            .values()
            .find(|i| storage_key(i) == key)
            .map_or(4, |i| i.dtype.size_in_bytes());
        let mut data = vec![0u8; count * elem];
        r.read_exact(&mut data)
            .with_context(|| format!("storage {key}: truncated file"))?;
        storages.insert(key, data);
    }
    infos
        .into_iter()
        .map(|(name, info)| {
            let t = tensor(&info, &storages).with_context(|| format!("tensor `{name}`"))?;
            Ok((name, t.to_device(device)?))
        })
        .collect()
}

/// Tensor infos of the state dict; the storage key is the last path part.
fn tensor_infos(obj: Object) -> anyhow::Result<HashMap<String, TensorInfo>> {
    let Object::Dict(entries) = obj else {
        bail!("the pickled object is not a dict");
    };
    // {"state_dict": {...}} wrappers, as training scripts often save
    let nested = entries.iter().position(|(k, v)| {
        *k == Object::Unicode("state_dict".into()) && matches!(v, Object::Dict(_))
    });
    let entries = match nested {
        Some(i) => match entries.into_iter().nth(i) {
            Some((_, Object::Dict(inner))) => inner,
            _ => unreachable!("checked above"),
        },
        None => entries,
    };
    let mut infos = HashMap::new();
    for (name, value) in entries {
        if let Some(info) = value.into_tensor_info(name, Path::new(""))? {
            infos.insert(info.name.clone(), info);
        }
    }
    Ok(infos)
}

fn storage_key(info: &TensorInfo) -> &str {
    info.path.rsplit('/').next().unwrap_or(&info.path)
}

fn tensor(info: &TensorInfo, storages: &HashMap<String, Vec<u8>>) -> anyhow::Result<Tensor> {
    let key = storage_key(info);
    let data = storages
        .get(key)
        .with_context(|| format!("storage {key} is missing from the file"))?;
    if !info.layout.is_contiguous() {
        bail!(
            "non-contiguous tensors are not supported ({:?})",
            info.layout
        );
    }
    let start = info.layout.start_offset();
    let len = info.layout.shape().elem_count() * info.dtype.size_in_bytes();
    let bytes = data
        .get(start..start + len)
        .with_context(|| format!("storage {key} is shorter than the tensor"))?;
    Ok(Tensor::from_raw_buffer(
        bytes,
        info.dtype,
        info.layout.dims(),
        &Device::Cpu,
    )?)
}
