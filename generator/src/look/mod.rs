//! The shared base of the look: range checks, the bundled HDRI names, the
//! per-lever random streams and the `[appearance.unseen_look]` config type.
//! The look is layered one way, each module importing only those below it:
//!
//! 1. `look` (this module): helpers and config types with no other look
//!    dependency;
//! 2. [`crate::appearance`]: the base appearance of `[appearance]`;
//! 3. [`crate::unseen_look`]: the held-out look of the `unseen_look`
//!    condition, drawn from the base appearance;
//! 4. [`crate::randomize`]: training's further levers, which also pick the
//!    sequence's appearance (training's or `unseen_look`'s) and check that
//!    training never reaches the held-out look.

pub mod checks;
pub mod sampling;
pub mod unseen_config;

pub use checks::BUNDLED_HDRIS;
pub(crate) use checks::{check_hdris, check_range};
pub(crate) use sampling::uniform;
pub use sampling::{lever_rng, world_light};
