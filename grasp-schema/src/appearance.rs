//! Domain randomization values of one sequence. They are sampled in Rust from
//! the sequence's own random stream and applied verbatim by the Blender
//! scripts, so a sequence can be re-rendered exactly from its metadata.

use serde::{Deserialize, Serialize};

/// A procedural (or image) material for a room surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurfaceMaterial {
    /// Texture family: `noise`, `voronoi`, `brick`, `checker`, `wave`,
    /// `marble`, `image`, or the held-out family reserved for `background`.
    pub family: String,
    /// Two linear RGB colours the pattern blends between.
    pub color_a: [f64; 3],
    pub color_b: [f64; 3],
    /// Pattern scale (texture coordinates per metre).
    pub scale: f64,
    pub roughness: f64,
    /// Family-specific extra parameter in [0, 1] (distortion, mortar size...).
    pub detail: f64,
    /// For `image`: path of the image texture.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
}

/// One light source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Light {
    /// `point`, `spot` or `area`.
    pub kind: String,
    pub position: [f64; 3],
    /// Power in watts (Blender units).
    pub power_w: f64,
    pub color_temperature_k: f64,
    /// Linear RGB multiplier of the colour temperature.
    pub tint: [f64; 3],
}

/// The object's material: kept from the catalog, or replaced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectMaterial {
    pub randomized: bool,
    pub color: [f64; 3],
    pub roughness: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Appearance {
    pub wall: SurfaceMaterial,
    pub floor: SurfaceMaterial,
    pub table: SurfaceMaterial,
    pub object: ObjectMaterial,
    pub lights: Vec<Light>,
    /// Camera exposure in stops.
    pub exposure: f64,
    /// Whether the hand is partly in view at the top of the frame.
    pub hand_visible: bool,
}
