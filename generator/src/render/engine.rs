//! The render engine (`[render] engine`), a setting of its own: the
//! device choice and the config both read it, and it imports nothing of
//! the generator's own.

use serde::{Deserialize, Serialize};

/// Render engine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Engine {
    /// Path tracing; the default, realistic with the denoiser at few samples.
    Cycles,
    /// Rasterised flat studio lighting: fast previews and tests.
    Workbench,
    /// Blender's real-time engine; meant for machines with a GPU.
    Eevee,
}
