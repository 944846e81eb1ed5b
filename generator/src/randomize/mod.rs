//! Training's broader randomisation: levers beyond the base appearance of
//! `[appearance]`, each switched by `enabled` in `[randomize.LEVER]` and
//! drawn from its own named sub-stream of the sequence's seed. Switching one
//! lever on or off therefore changes no value drawn by another (tested), so
//! an ablation removes exactly one kind of variation.
//!
//! | lever | what varies | where it acts |
//! |---|---|---|
//! | `fov` | lens field of view (scale of tan(half FOV)) | plan intrinsics, Blender camera |
//! | `principal_point` | principal point (Blender camera shift) | plan intrinsics |
//! | `sensor_noise` | additive Gaussian noise | Rust, after the render |
//! | `motion_blur` | shutter along the keyframed path | Cycles |
//! | `white_balance` | per-channel gains | Rust, after the render |
//! | `jpeg` | JPEG round trip at a random quality | Rust, after the render |
//! | `world_light` | a bundled studio-light HDRI, rotation, strength | Blender world |
//! | `object_color` | the object's colour within its plausible range | object material |
//! | `distractors` | primitives on the table, clear of the target and the reach | plan, Blender |
//! | `proportions` | the object's proportions (mesh and part boxes, per axis, size kept) | plan, Blender, part labels |
//! | `surface` | the object's edges rounded, a relief in its shading | Blender |
//! | `standoff` | where the approach stops short of the target | plan |
//! | `aim` | the aim point within the target part's end face | plan |
//! | `approach_ends` | both ends of the part's approach axis, balanced | plan |
//!
//! The `unseen_look` condition takes its appearance from
//! `[appearance.unseen_look]` instead (see [`crate::unseen_look`]); of these
//! levers it keeps the geometric ones (principal point, object colour,
//! distractors, proportions, surface, standoff, aim, approach ends).

//!
//! The lever config types are in `levers`, their checks in `validate`, the
//! draws in `sample`; helpers shared with the rest of the look are in
//! [`crate::look`].

mod levers;
mod sample;
mod validate;

pub use crate::look::{lever_rng, world_light, BUNDLED_HDRIS};
pub use levers::*;
pub use sample::*;
pub use validate::check_unseen_disjoint;
