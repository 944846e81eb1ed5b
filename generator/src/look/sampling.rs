//! Sampling helpers shared by the look: the per-lever random streams, a
//! uniform draw and a world light.

use grasp_schema::appearance::WorldLight;
use grasp_schema::plan::substream_seed;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Uniform in [lo, hi) (lo for an empty range).
pub(crate) fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        rng.gen_range(lo..hi)
    } else {
        lo
    }
}

/// The RNG of one lever of one sequence.
pub fn lever_rng(stream: u64, lever: &str) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(substream_seed(stream, lever))
}

/// One world light from `hdris`: which image, its rotation and strength.
pub fn world_light(rng: &mut ChaCha8Rng, hdris: &[String], strength: [f64; 2]) -> WorldLight {
    let i = rng.gen_range(0..hdris.len().max(1));
    WorldLight {
        hdri: hdris.get(i).cloned().unwrap_or_else(|| "studio".into()),
        rotation_deg: uniform(rng, [0.0, 360.0]),
        strength: uniform(rng, strength),
    }
}
