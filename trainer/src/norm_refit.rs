//! Re-estimating the frozen backbone's batch-norm statistics on the frames
//! it will read (AdaBN): at training on a sample of the training frames, at
//! evaluation on a sample of each evaluated set's own frames, unlabelled.
//! The sample is spread evenly over every frame of the set, so that it
//! covers all objects and the whole approach, and it is deterministic.

use crate::data::{BadData, Dataset};
use anyhow::{Context, Result};
use grasp_model::backbone::Backbone;
use image::RgbImage;

/// The fewest frames a refit accepts: fewer give noisy statistics.
pub const MIN_FRAMES: usize = 16;

/// Re-estimates `backbone`'s batch norms on `frames` frames of `data`, as
/// the feature extractor would receive them (cropped, probed).
pub fn refit(backbone: &mut Backbone, data: &Dataset, frames: usize, bad: &BadData) -> Result<()> {
    anyhow::ensure!(
        frames >= MIN_FRAMES,
        "re-estimating batch norm needs at least {MIN_FRAMES} frames, got {frames}"
    );
    let images = sample_frames(data, frames, bad)?;
    anyhow::ensure!(
        images.len() >= MIN_FRAMES,
        "only {} readable frames in {} to re-estimate batch norm on (at least {MIN_FRAMES})",
        images.len(),
        data.root.display()
    );
    tracing::info!(
        "re-estimating batch norm on {} frames of {}",
        images.len(),
        data.root.display()
    );
    backbone
        .refit_batch_norm(&images)
        .with_context(|| format!("re-estimating batch norm on {}", data.root.display()))
}

/// Up to `n` frames of `data`, evenly spaced over all its frames in order
/// (every frame when it has fewer). Unreadable frames are reported to `bad`
/// and left out.
pub fn sample_frames(data: &Dataset, n: usize, bad: &BadData) -> Result<Vec<RgbImage>> {
    let mut out = Vec::with_capacity(n);
    for (s, i) in evenly_spaced(&frame_counts(data), n) {
        out.extend(data.sequences[s].load_frame(i, bad)?);
    }
    Ok(out)
}

fn frame_counts(data: &Dataset) -> Vec<usize> {
    data.sequences.iter().map(|s| s.frames.len()).collect()
}

/// `(sequence, frame)` of `n` frames spread evenly over sequences with
/// `counts` frames each: frame `floor((k + 1/2) total / n)` of the whole for
/// k = 0..n (all of them when `n >= total`).
fn evenly_spaced(counts: &[usize], n: usize) -> Vec<(usize, usize)> {
    let total: usize = counts.iter().sum();
    let picks: Vec<usize> = if n >= total {
        (0..total).collect()
    } else {
        // Integer form of floor((k + 1/2) * total / n): exact at any size.
        (0..n).map(|k| ((2 * k + 1) * total) / (2 * n)).collect()
    };
    let mut out = Vec::with_capacity(picks.len());
    let (mut seq, mut start) = (0, 0);
    for p in picks {
        while p >= start + counts[seq] {
            start += counts[seq];
            seq += 1;
        }
        out.push((seq, p - start));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picks_spread_over_every_sequence_in_order() {
        let picks = evenly_spaced(&[4, 0, 4, 4], 6);
        assert_eq!(picks, vec![(0, 1), (0, 3), (2, 1), (2, 3), (3, 1), (3, 3)]);
    }

    #[test]
    fn asking_for_more_than_there_is_takes_everything() {
        let picks = evenly_spaced(&[2, 1], 10);
        assert_eq!(picks, vec![(0, 0), (0, 1), (1, 0)]);
        assert!(evenly_spaced(&[], 5).is_empty());
        assert!(evenly_spaced(&[0, 0], 5).is_empty());
    }

    #[test]
    fn one_pick_is_the_middle_frame_and_picks_never_repeat() {
        assert_eq!(evenly_spaced(&[3, 3, 3], 1), vec![(1, 1)]);
        let picks = evenly_spaced(&[7; 1000], 4999);
        let mut sorted = picks.clone();
        sorted.dedup();
        assert_eq!(sorted.len(), 4999, "a frame was picked twice");
        assert!(picks.iter().all(|&(s, f)| s < 1000 && f < 7));
    }
}
