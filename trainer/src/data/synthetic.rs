//! Tiny learnable datasets for tests, examples and benchmarks, written in
//! the generator's layout (with `sequence.json` and `manifest.jsonl`) or in
//! the authors' real-data layout (frames only). Each class has its own
//! colour and stripe pattern under per-frame noise and brightness changes,
//! so a classifier can beat chance while still having to generalise.

use crate::error::DataError;
use grasp_schema::dataset::{
    camera_dir, frame_file_name, sequence_dir_name, ManifestEntry, SequenceRecord, MANIFEST_FILE,
    SEQUENCE_FILE, WRIST_CAMERA_FOLDER,
};
use grasp_schema::plan::{
    CameraIntrinsics, Condition, FramePlan, ObjectPlacement, Pose, SequenceKey, SequencePlan,
    PLAN_SCHEMA_VERSION,
};
use grasp_schema::taxonomy::{Class, GraspType, Preshape};
use image::{Rgb, RgbImage};
use rand::Rng;
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// The generator's: per-frame labels in `sequence.json`.
    Generated,
    /// The authors' real data: no metadata, labels from the folder.
    Authors,
}

/// (category, object, [(part, pre-shape)]).
pub type ObjectSpec = (String, String, Vec<(String, Preshape)>);

#[derive(Debug, Clone)]
pub struct SyntheticSpec {
    pub layout: Layout,
    pub objects: Vec<ObjectSpec>,
    pub sequences_per_part: usize,
    pub frames: usize,
    pub fps: f64,
    /// Frames labelled `no_grasp` at the end of each sequence.
    pub no_grasp_frames: usize,
    pub size: u32,
    /// Pixel noise amplitude (0-255).
    pub noise: f32,
    pub seed: u64,
}

impl SyntheticSpec {
    /// Four objects covering the four pre-shapes, one of them with two
    /// parts (a multi-grasp object).
    pub fn small(layout: Layout) -> SyntheticSpec {
        let part = |n: &str, p| (n.to_string(), p);
        SyntheticSpec {
            layout,
            objects: vec![
                (
                    "can".into(),
                    "010_can".into(),
                    vec![part("body", Preshape::Power)],
                ),
                (
                    "mug".into(),
                    "025_mug".into(),
                    vec![
                        part("body", Preshape::Power),
                        part("handle", Preshape::Lateral),
                    ],
                ),
                (
                    "plate".into(),
                    "029_plate".into(),
                    vec![part("rim", Preshape::Pinch)],
                ),
                (
                    "marker".into(),
                    "040_marker".into(),
                    vec![part("body", Preshape::Pinch3)],
                ),
            ],
            sequences_per_part: 4,
            frames: 10,
            fps: 10.0,
            no_grasp_frames: 2,
            size: 32,
            noise: 12.0,
            seed: 0,
        }
    }
}

const COLOURS: [[f32; 3]; Class::COUNT] = [
    [200.0, 60.0, 60.0],
    [60.0, 190.0, 70.0],
    [70.0, 80.0, 210.0],
    [210.0, 200.0, 60.0],
    [128.0, 128.0, 128.0],
];

/// A frame of class `class`: its colour, stripes of a class-specific period,
/// random brightness and pixel noise.
pub fn class_image(class: Class, size: u32, noise: f32, rng: &mut impl Rng) -> RgbImage {
    let base = COLOURS[class.index()];
    let period = 2 + class.index() as u32 * 2;
    let gain: f32 = rng.gen_range(0.8..1.2);
    RgbImage::from_fn(size, size, |x, y| {
        let stripe = if ((x + y) / period).is_multiple_of(2) {
            1.0
        } else {
            0.6
        };
        let mut px = |c: f32| {
            let n = if noise > 0.0 {
                rng.gen_range(-noise..noise)
            } else {
                0.0
            };
            (c * stripe * gain + n).clamp(0.0, 255.0) as u8
        };
        Rgb([px(base[0]), px(base[1]), px(base[2])])
    })
}

/// Writes the dataset under `root`.
pub fn write_synthetic(root: &Path, spec: &SyntheticSpec) -> Result<(), DataError> {
    let mut rng = crate::rng::stream(spec.seed, "synthetic");
    let mut manifest = Vec::new();
    let mut number = 0u64;
    for (category, object, parts) in &spec.objects {
        for (part, preshape) in parts {
            for index in 0..spec.sequences_per_part {
                let dir = camera_dir(root, category, object, *preshape, WRIST_CAMERA_FOLDER)
                    .join(sequence_dir_name(number, 5));
                number += 1;
                let labels = sequence_labels(spec, *preshape);
                let files = write_frames(&dir, spec, &labels, &mut rng)?;
                if spec.layout == Layout::Generated {
                    let record = record(
                        spec, category, object, part, *preshape, index, &labels, files,
                    );
                    write_file(&dir.join(SEQUENCE_FILE), serde_json::to_string(&record)?)?;
                    manifest.push(ManifestEntry {
                        id: record.plan.key.id(),
                        path: dir
                            .strip_prefix(root)
                            .unwrap_or(&dir)
                            .to_string_lossy()
                            .replace('\\', "/"),
                        object: object.clone(),
                        part: part.clone(),
                        grasp_type: record.plan.grasp_type,
                        preshape: *preshape,
                        condition: Condition::Default,
                        frames: spec.frames,
                    });
                }
            }
        }
    }
    if spec.layout == Layout::Generated {
        let mut lines = String::new();
        for m in manifest {
            lines.push_str(&serde_json::to_string(&m)?);
            lines.push('\n');
        }
        write_file(&root.join(MANIFEST_FILE), lines)?;
    }
    Ok(())
}

/// The pre-shape, then `no_grasp` for the last `spec.no_grasp_frames`.
fn sequence_labels(spec: &SyntheticSpec, preshape: Preshape) -> Vec<Class> {
    (0..spec.frames)
        .map(|i| {
            if i + spec.no_grasp_frames >= spec.frames {
                Class::NoGrasp
            } else {
                Class::from(preshape)
            }
        })
        .collect()
}

/// Creates `dir` and writes one frame per label into it: the file names.
fn write_frames(
    dir: &Path,
    spec: &SyntheticSpec,
    labels: &[Class],
    rng: &mut impl Rng,
) -> Result<Vec<String>, DataError> {
    std::fs::create_dir_all(dir).map_err(|source| DataError::Create {
        path: dir.to_path_buf(),
        source,
    })?;
    let pad = grasp_schema::dataset::padding_for(spec.frames as u64);
    let mut files = Vec::new();
    for (i, class) in labels.iter().enumerate() {
        let name = frame_file_name(i as u64, pad);
        let path = dir.join(&name);
        class_image(*class, spec.size, spec.noise, rng)
            .save(&path)
            .map_err(|source| DataError::WriteImage { path, source })?;
        files.push(name);
    }
    Ok(files)
}

fn write_file(path: &Path, text: String) -> Result<(), DataError> {
    std::fs::write(path, text).map_err(|source| DataError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[allow(clippy::too_many_arguments)]
fn record(
    spec: &SyntheticSpec,
    category: &str,
    object: &str,
    part: &str,
    preshape: Preshape,
    index: usize,
    labels: &[Class],
    files: Vec<String>,
) -> SequenceRecord {
    let identity = Pose {
        position: [0.0; 3],
        rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    let key = SequenceKey {
        object: object.to_string(),
        part: part.to_string(),
        index: index as u32,
        condition: Condition::Default,
    };
    let s = f64::from(spec.size);
    SequenceRecord {
        plan: SequencePlan {
            schema_version: PLAN_SCHEMA_VERSION,
            dataset_seed: spec.seed,
            stream_seed: key.stream_seed(spec.seed),
            key,
            category: category.to_string(),
            grasp_type: preshape
                .grasp_types()
                .first()
                .copied()
                .unwrap_or(GraspType::MediumWrap),
            preshape,
            part_index: 0,
            fps: spec.fps,
            duration_s: spec.frames as f64 / spec.fps,
            intrinsics: CameraIntrinsics {
                width: spec.size,
                height: spec.size,
                fx: s,
                fy: s,
                cx: s / 2.0,
                cy: s / 2.0,
                fov_x_deg: 53.0,
                fov_y_deg: 53.0,
                clip_near: 0.01,
                clip_far: 10.0,
            },
            object: ObjectPlacement {
                pose: identity,
                yaw_deg: 0.0,
                upside_down: false,
                on_table_border: false,
                scale: 1.0,
                proportions: [1.0; 3],
            },
            target: [0.0; 3],
            other_end: [0.0; 3],
            frames: labels
                .iter()
                .enumerate()
                .map(|(i, c)| FramePlan {
                    index: i as u32,
                    time_s: i as f64 / spec.fps,
                    camera: identity,
                    class: *c,
                    head_camera: None,
                })
                .collect(),
            sampled: Default::default(),
            appearance: None,
            distractors: Vec::new(),
        },
        frame_files: files,
        render: serde_json::json!({"engine": "synthetic-test-pattern"}),
        generator_version: concat!("trainer-synthetic-", env!("CARGO_PKG_VERSION")).to_string(),
    }
}
