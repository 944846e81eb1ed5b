//! Size limits of a config, checked before anything is planned. Each field
//! alone may be valid while the whole does not fit: 7.5 million frames per
//! sequence make one plan several GB; `sequences_per_pair = 1e9` makes the
//! key list alone exhaust memory; a 100000-pixel-wide frame makes every
//! Blender worker fail. Such a config is refused at once, naming the field,
//! the size it asks for and the limit.

use super::error::{PlanError, Result};
use super::{DatasetConfig, PlanConfig};
use grasp_schema::Condition;

/// Frames of one sequence (per camera). A plan costs about 1.2 KB per
/// frame in the planner (120 MB at this limit, measured with
/// `grasp-gen plan`), and the worker receives it as one JSON message.
pub const MAX_FRAMES_PER_SEQUENCE: u64 = 100_000;
/// Sequences of a whole dataset (every shard): the parent holds every key
/// and its folder (a few hundred bytes each).
pub const MAX_SEQUENCES: u64 = 1_000_000;
/// Pixels of one frame (4096 x 4096). Blender's render buffers take on the
/// order of 100 bytes per pixel with Cycles' denoising passes, so this is
/// about 1.7 GB per worker.
pub const MAX_FRAME_PIXELS: u64 = 4096 * 4096;
/// Pixels of one sequence, all frames and cameras together: 2^30, i.e.
/// 3 GiB of RGB8 before compression, the unit a reader (preview, trainer,
/// `dataset verify --decode`) goes through and a worker writes at once.
pub const MAX_SEQUENCE_PIXELS: u64 = 1 << 30;

/// Fails when the config asks for more than the limits above; `pairs` is
/// the number of (object, part) pairs it selects.
pub fn check_size(d: &DatasetConfig, plan: &PlanConfig, pairs: usize) -> Result<()> {
    let sequences = pairs as u128 * d.conditions.len() as u128 * u128::from(d.sequences_per_pair);
    if sequences > u128::from(MAX_SEQUENCES) {
        return Err(PlanError::TooBig {
            field: format!("dataset.sequences_per_pair = {}", d.sequences_per_pair),
            reason: format!(
                "{pairs} pairs x {} conditions x {} = {sequences} \
                 sequences; the limit is {MAX_SEQUENCES} sequences per dataset (split a bigger \
                 dataset into several configs with different dataset.seed)",
                d.conditions.len(),
                d.sequences_per_pair
            ),
        });
    }
    let [w, h] = plan.camera.resolution;
    let pixels = u64::from(w) * u64::from(h);
    if pixels > MAX_FRAME_PIXELS {
        return Err(PlanError::TooBig {
            field: format!("plan.camera.resolution = [{w}, {h}]"),
            reason: format!(
                "{pixels} pixels per frame; the limit is \
                 {MAX_FRAME_PIXELS} (4096 x 4096): Blender's buffers for one frame would need \
                 about {:.0} GB per worker",
                pixels as f64 * 100.0 / 1e9
            ),
        });
    }
    let cameras: u64 = if plan.head_camera.enabled { 2 } else { 1 };
    for &c in &d.conditions {
        let (field, seconds) = duration_field(plan, c);
        let frames = (seconds * plan.trajectory.fps).round();
        if frames.is_nan() || frames > MAX_FRAMES_PER_SEQUENCE as f64 {
            return Err(PlanError::TooManyFrames {
                field,
                seconds,
                fps: plan.trajectory.fps,
                frames,
                condition: c,
                limit: MAX_FRAMES_PER_SEQUENCE,
            });
        }
        let total = frames as u64 * pixels * cameras;
        if total > MAX_SEQUENCE_PIXELS {
            return Err(PlanError::TooBig {
                field: "plan.camera.resolution x frames".into(),
                reason: format!(
                    "a {} sequence has {frames} frames of \
                     {w}x{h}{} = {:.1} Gpixels ({:.1} GiB as RGB8); the limit is {:.1} Gpixels per \
                     sequence (lower plan.camera.resolution, {field} or plan.trajectory.fps)",
                    c.name(),
                    if cameras == 2 { " from 2 cameras" } else { "" },
                    total as f64 / 1e9,
                    total as f64 * 3.0 / f64::from(1u32 << 30),
                    MAX_SEQUENCE_PIXELS as f64 / 1e9
                ),
            });
        }
    }
    Ok(())
}

/// The config field that sets the length of `condition`'s sequences.
fn duration_field(plan: &PlanConfig, condition: Condition) -> (&'static str, f64) {
    let c = &plan.conditions;
    match condition {
        Condition::Default | Condition::Background | Condition::UnseenLook => {
            ("plan.trajectory.duration_s", plan.trajectory.duration_s)
        }
        Condition::Fast => ("plan.conditions.fast.duration_s", c.fast.duration_s),
        Condition::Seated => ("plan.conditions.seated.duration_s", c.seated.duration_s),
        Condition::FromGround => (
            "plan.conditions.from_ground.duration_s",
            c.from_ground.duration_s,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::GeneratorConfig;

    fn err(config: &GeneratorConfig, pairs: usize) -> String {
        format!(
            "{:#}",
            check_size(&config.dataset, &config.plan, pairs).unwrap_err()
        )
    }

    #[test]
    fn the_defaults_and_the_paper_scale_fit() {
        let mut c = GeneratorConfig::default();
        check_size(&c.dataset, &c.plan, 31).unwrap();
        c.dataset.conditions = Condition::ALL.to_vec();
        check_size(&c.dataset, &c.plan, 31).unwrap();
    }

    #[test]
    fn each_limit_names_its_field() {
        let mut c = GeneratorConfig::default();
        c.dataset.sequences_per_pair = 1_000_000_000;
        assert!(err(&c, 31).contains("dataset.sequences_per_pair = 1000000000"));

        let mut c = GeneratorConfig::default();
        c.plan.trajectory.fps = 2_500_000.0; // 7.5 million frames in 3 s
        assert!(err(&c, 1).contains("plan.trajectory.duration_s x plan.trajectory.fps"));

        let mut c = GeneratorConfig::default();
        c.plan.camera.resolution = [100_000, 100_000];
        assert!(err(&c, 1).contains("plan.camera.resolution = [100000, 100000]"));

        let mut c = GeneratorConfig::default();
        c.plan.camera.resolution = [4096, 4096];
        assert!(err(&c, 1).contains("plan.camera.resolution x frames"));

        let mut c = GeneratorConfig::default();
        c.dataset.conditions = vec![Condition::Fast];
        c.plan.conditions.fast.duration_s = 1e6;
        assert!(err(&c, 1).contains("plan.conditions.fast.duration_s"));
    }
}
