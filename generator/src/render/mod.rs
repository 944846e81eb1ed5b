//! Rendering orchestration with headless Blender workers. (Owned by the
//! rendering work; to be filled in.)

use serde::{Deserialize, Serialize};

/// Engine and output settings.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {}
