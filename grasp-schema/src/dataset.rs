//! The on-disk dataset layout shared by the generator (writer) and the trainer
//! (reader). It is the authors' layout, so their experiments code reads it:
//!
//! ```text
//! ROOT/manifest.jsonl
//! ROOT/CATEGORY/OBJECT/PRESHAPE_FOLDER/Wrist_d435/rgbNNNNN/NNNNN.png
//! ROOT/CATEGORY/OBJECT/PRESHAPE_FOLDER/Wrist_d435/rgbNNNNN/sequence.json
//! ROOT/CATEGORY/OBJECT/PRESHAPE_FOLDER/Head_d435/rgbNNNNN/...   (optional)
//! ```
//!
//! The optional egocentric camera's folder holds the same frame names and
//! the same `sequence.json` as its wrist folder; the manifest lists the
//! wrist folders only.
//!
//! `PRESHAPE_FOLDER` is the authors' folder name (`power_no3`, `lateral_no3`,
//! `pinch_no3`, `pinch_3`).

use crate::plan::SequencePlan;
use crate::taxonomy::Preshape;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const MANIFEST_FILE: &str = "manifest.jsonl";
pub const SEQUENCE_FILE: &str = "sequence.json";
pub const WRIST_CAMERA_FOLDER: &str = "Wrist_d435";
pub const HEAD_CAMERA_FOLDER: &str = "Head_d435";
/// Minimum zero padding of sequence folders and frame files.
pub const MIN_PADDING: usize = 5;

/// Padding wide enough for `count` numbers (0..count) and at least
/// [`MIN_PADDING`], so numbers never overflow their padding and names sort.
pub fn padding_for(count: u64) -> usize {
    let max = count.saturating_sub(1);
    let digits = if max == 0 {
        1
    } else {
        max.ilog10() as usize + 1
    };
    digits.max(MIN_PADDING)
}

/// `ROOT/CATEGORY/OBJECT/PRESHAPE_FOLDER/CAMERA_FOLDER`.
pub fn camera_dir(
    root: &Path,
    category: &str,
    object: &str,
    preshape: Preshape,
    camera_folder: &str,
) -> PathBuf {
    root.join(category)
        .join(object)
        .join(preshape.authors_folder())
        .join(camera_folder)
}

/// Name of a sequence folder: `rgb` + zero-padded number.
pub fn sequence_dir_name(number: u64, padding: usize) -> String {
    format!("rgb{number:0padding$}")
}

/// Name of a frame file inside a sequence folder.
pub fn frame_file_name(index: u64, padding: usize) -> String {
    format!("{index:0padding$}.png")
}

/// Per-sequence metadata written next to the frames as `sequence.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequenceRecord {
    /// The plan the sequence was rendered from (labels, times, poses,
    /// intrinsics, all sampled values).
    pub plan: SequencePlan,
    /// Frame file names, in frame order (same length as `plan.frames`).
    pub frame_files: Vec<String>,
    /// Render settings (engine, samples, denoiser, resolution, passes...).
    pub render: serde_json::Value,
    /// Version of the generator that wrote it.
    pub generator_version: String,
}

/// Name of the `part` pass's label image of a frame: `partNNNNN.png` next to
/// `NNNNN.png` (8-bit; 0 = background, k = the k-th name of
/// [`SequenceRecord::part_labels`]).
pub fn part_file_name(frame_file: &str) -> String {
    format!("part{frame_file}")
}

/// Key of the part names (label k is entry k - 1) inside
/// [`SequenceRecord::render`], present when the `part` pass was rendered.
pub const PART_LABELS_KEY: &str = "part_labels";

/// Key of the rendered centre region inside [`SequenceRecord::render`]
/// (`[render] center_region`), present when it is below 1.
pub const CENTER_REGION_KEY: &str = "center_region";

/// Key of the world that drew the frames inside [`SequenceRecord::render`]
/// (`[render] world`): `studio` is training's scene, anything else a
/// test world no training set may draw from. Records written before the key
/// existed are studio renders.
pub const WORLD_KEY: &str = "world";

/// The world of records that predate [`WORLD_KEY`], and the default.
pub const STUDIO_WORLD: &str = "studio";

/// The centred square whose side is `fraction` of the shorter side of a
/// `width` x `height` image (at least one pixel), as `(x, y, side)`: what a
/// model's centre crop sees and what a `center_region` render draws.
pub fn centre_square(width: u32, height: u32, fraction: f64) -> (u32, u32, u32) {
    let short = width.min(height);
    let side =
        ((f64::from(short) * fraction.clamp(0.0, 1.0)).round() as u32).clamp(1, short.max(1));
    (
        width.saturating_sub(side) / 2,
        height.saturating_sub(side) / 2,
        side,
    )
}

/// The fraction of the shorter side of a `width` x `height` frame that a
/// centred square spanning `angle_deg` (its full width, in degrees) covers
/// through a lens of focal length `fx` pixels: 2 fx tan(angle / 2) / shorter
/// side. A model that crops a fixed angle sees the same part of the world
/// at every lens, where a fixed fraction sees more of it through a wider
/// one. None for a non-finite or non-positive angle or focal length, an
/// angle of 180 degrees or more, or an empty frame; the fraction may exceed
/// 1 for a lens too narrow to hold the angle.
pub fn angle_crop_fraction(angle_deg: f64, fx: f64, width: u32, height: u32) -> Option<f64> {
    let short = f64::from(width.min(height));
    let valid = angle_deg.is_finite()
        && angle_deg > 0.0
        && angle_deg < 180.0
        && fx.is_finite()
        && fx > 0.0
        && short > 0.0;
    valid.then(|| 2.0 * fx * (angle_deg.to_radians() / 2.0).tan() / short)
}

/// The full angle, in degrees, that the centred square of `fraction` of the
/// shorter side spans through a lens of focal length `fx` pixels: the
/// inverse of [`angle_crop_fraction`].
pub fn crop_angle_deg(fraction: f64, fx: f64, width: u32, height: u32) -> f64 {
    let short = f64::from(width.min(height));
    2.0 * (fraction * short / (2.0 * fx)).atan().to_degrees()
}

/// Why a model whose centre crop is `crop` (a fraction of the shorter
/// side; None: the whole frame) cannot look at frames rendered only in
/// their central `region` (`[render] center_region`): it would see the
/// black surround. None when it can.
pub fn crop_outside_region(region: f64, crop: Option<f64>) -> Option<String> {
    let seen = crop.unwrap_or(1.0);
    (seen > region + 1e-9).then(|| {
        format!(
            "the frames were rendered only in their central {region} (render.center_region) \
             but the model looks at the central {seen} (its centre crop; 1 is the whole \
             frame): crop at most {region}, or render with a larger center_region"
        )
    })
}

/// Key of [`RenderCost`] inside [`SequenceRecord::render`].
pub const RENDER_COST_KEY: &str = "cost";

/// Wall-clock render cost of one sequence, measured in the worker. It is
/// stored under `render.cost` of the record (the record's `render` value is
/// free-form), so records written before it existed still read.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RenderCost {
    /// Seconds spent swapping in the object and applying the appearance.
    #[serde(default)]
    pub setup_seconds: f64,
    /// Seconds spent rendering and writing the frames, per camera folder
    /// (`Wrist_d435`, `Head_d435`), including the part labels and the
    /// image-space effects.
    #[serde(default)]
    pub camera_seconds: std::collections::BTreeMap<String, f64>,
    /// Of those, the seconds spent on image-space camera effects (white
    /// balance, blur, noise, JPEG) over all cameras.
    #[serde(default)]
    pub effects_seconds: f64,
    /// CPU seconds (user + system, every thread) the worker process spent
    /// on the sequence: less sensitive than wall-clock time to other load on
    /// the machine. 0 where the platform does not report it.
    #[serde(default)]
    pub cpu_seconds: f64,
    /// The device that rendered the sequence (`cpu`, `optix`, `cuda`, ...;
    /// `gpu_module` for Workbench and EEVEE), which `[render] device =
    /// "auto"` leaves to the machine. Empty in records written before it
    /// was recorded (those were all rendered on the CPU).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub device: String,
}

impl SequenceRecord {
    /// The sequence's render cost, when the record carries one.
    pub fn render_cost(&self) -> Option<RenderCost> {
        let v = self.render.get(RENDER_COST_KEY)?;
        serde_json::from_value(v.clone()).ok()
    }

    /// The device that rendered the sequence ([`RenderCost::device`]), when
    /// the record says.
    pub fn render_device(&self) -> Option<String> {
        Some(self.render_cost()?.device).filter(|d| !d.is_empty())
    }

    /// The object's part names in label order (label k is entry k - 1),
    /// when the sequence has the `part` pass.
    pub fn part_labels(&self) -> Option<Vec<String>> {
        let v = self.render.get(PART_LABELS_KEY)?;
        serde_json::from_value(v.clone()).ok()
    }

    /// The side of the centred square that was rendered, as a fraction of
    /// the shorter image side (pixels outside it are black); 1 when the
    /// whole frame was rendered. `None` when the record's value is not a
    /// fraction in (0, 1].
    pub fn center_region(&self) -> Option<f64> {
        match self.render.get(CENTER_REGION_KEY) {
            None => Some(1.0),
            Some(v) => v.as_f64().filter(|f| *f > 0.0 && *f <= 1.0),
        }
    }

    /// The world that drew the frames (`studio`, `foreign`, ...): `studio`
    /// when the record predates the key, `None` when its value is not a
    /// string. Only studio sequences may go into a training set.
    pub fn world(&self) -> Option<String> {
        match self.render.get(WORLD_KEY) {
            None => Some(STUDIO_WORLD.to_string()),
            Some(v) => v.as_str().map(str::to_string),
        }
    }

    /// Why the sequence belongs to a test world no training set may draw
    /// from: another render world (`render.world = "foreign"`, or an
    /// unreadable one) or a held-out reach (`dataset.held_out`, recorded
    /// as the plan's `sampled.held_out`). None for training's own world.
    pub fn test_world(&self) -> Option<String> {
        match self.world() {
            Some(w) if w == STUDIO_WORLD => {}
            Some(w) => return Some(format!("render.world = \"{w}\"")),
            None => return Some(format!("render.{WORLD_KEY} is not a name")),
        }
        self.plan
            .sampled
            .get("held_out")
            .map(|w| format!("dataset.held_out = {w}"))
    }

    /// Whether the plan has an egocentric view (a `Head_d435` folder).
    pub fn has_head_camera(&self) -> bool {
        self.plan.frames.iter().any(|f| f.head_camera.is_some())
    }
}

/// The head camera's sequence folder next to a wrist camera's one: the same
/// path with the `Wrist_d435` component replaced (`/`-separated paths).
pub fn head_sequence_dir(wrist_dir: &str) -> Option<String> {
    let parts: Vec<&str> = wrist_dir.split('/').collect();
    let i = parts.iter().rposition(|p| *p == WRIST_CAMERA_FOLDER)?;
    let mut out = parts;
    out[i] = HEAD_CAMERA_FOLDER;
    Some(out.join("/"))
}

/// One line of `ROOT/manifest.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestEntry {
    /// `SequenceKey::id()` of the sequence.
    pub id: String,
    /// Sequence folder, relative to the dataset root, with `/` separators.
    pub path: String,
    pub object: String,
    pub part: String,
    pub grasp_type: crate::taxonomy::GraspType,
    pub preshape: Preshape,
    pub condition: crate::plan::Condition,
    pub frames: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fixed_angle_takes_a_smaller_fraction_through_a_wider_lens() {
        // The d435 preset at 224 px: fx 291.77 (42 degrees across).
        let angle = crop_angle_deg(0.42, 291.77, 224, 224);
        assert!((angle - 18.317).abs() < 1e-3, "{angle}");
        let at = |fx: f64| angle_crop_fraction(angle, fx, 224, 224).unwrap();
        assert!((at(291.77) - 0.42).abs() < 1e-12);
        // tan(half FOV) x 1.5: the same angle is 1/1.5 of the frame.
        assert!((at(291.77 / 1.5) - 0.28).abs() < 1e-12);
        // The shorter side counts, as for the fraction crop.
        let wide = angle_crop_fraction(angle, 291.77, 300, 224).unwrap();
        assert!((wide - 0.42).abs() < 1e-12);
        // A lens too narrow to hold the angle asks for more than the frame.
        assert!(at(291.77 / 0.4) > 1.0);
    }

    #[test]
    fn degenerate_angles_and_lenses_have_no_fraction() {
        for (angle, fx, w, h) in [
            (0.0, 300.0, 224, 224),
            (-5.0, 300.0, 224, 224),
            (180.0, 300.0, 224, 224),
            (f64::NAN, 300.0, 224, 224),
            (18.0, 0.0, 224, 224),
            (18.0, f64::INFINITY, 224, 224),
            (18.0, 300.0, 0, 224),
        ] {
            assert_eq!(
                angle_crop_fraction(angle, fx, w, h),
                None,
                "{angle} {fx} {w}x{h}"
            );
        }
    }

    #[test]
    fn padding_grows_instead_of_overflowing() {
        assert_eq!(padding_for(0), 5);
        assert_eq!(padding_for(1), 5);
        assert_eq!(padding_for(100_000), 5);
        assert_eq!(padding_for(100_001), 6);
        assert_eq!(padding_for(u64::MAX), 20);
        assert_eq!(sequence_dir_name(7, 5), "rgb00007");
        assert_eq!(
            sequence_dir_name(123_456, padding_for(200_000)),
            "rgb123456"
        );
        assert_eq!(frame_file_name(89, 5), "00089.png");
    }

    #[test]
    fn head_folder_sits_next_to_the_wrist_folder() {
        assert_eq!(
            head_sequence_dir("mug/025_mug/pinch_3/Wrist_d435/rgb00003").as_deref(),
            Some("mug/025_mug/pinch_3/Head_d435/rgb00003")
        );
        assert_eq!(head_sequence_dir("mug/025_mug/pinch_3/rgb00003"), None);
    }

    #[test]
    fn layout_uses_the_authors_folder_names() {
        let dir = camera_dir(
            Path::new("/data"),
            "mug",
            "025_mug",
            Preshape::Pinch3,
            WRIST_CAMERA_FOLDER,
        );
        assert_eq!(dir, PathBuf::from("/data/mug/025_mug/pinch_3/Wrist_d435"));
    }
}
