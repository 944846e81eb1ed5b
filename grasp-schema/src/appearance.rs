//! Domain randomization values of one sequence. They are sampled in Rust from
//! the sequence's own random stream and applied verbatim by the Blender
//! scripts, so a sequence can be re-rendered exactly from its metadata.

use serde::{Deserialize, Serialize};

/// A procedural (or image) material for a room surface, a distractor or
/// the table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurfaceMaterial {
    /// Texture family: `noise`, `voronoi`, `brick`, `checker`, `wave`,
    /// `marble`, `image`, the held-out family reserved for `background`, or
    /// one of the families reserved for the `unseen_look` condition and the
    /// other held-out looks (`dots`, `gabor`, `magic`, `mosaic`, `rings`,
    /// `chevron`, `triangles`).
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
    /// `point`, `spot` or `area` (training), `sun` or `ring` (a small area
    /// light of the `unseen_look` condition's ring).
    pub kind: String,
    /// Where the light sits; it points at the object. A `sun` is a
    /// direction only: the light arrives from this point's direction.
    pub position: [f64; 3],
    /// Power in watts (Blender units); a `sun`'s strength in W/m^2.
    pub power_w: f64,
    pub color_temperature_k: f64,
    /// Linear RGB multiplier of the colour temperature.
    pub tint: [f64; 3],
}

/// The object's material: kept from the catalog, replaced by a random one,
/// or (`plausible`) a colour drawn from the object's plausible range.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectMaterial {
    /// A fully random colour (`color`).
    pub randomized: bool,
    pub color: [f64; 3],
    pub roughness: f64,
    /// `color` was drawn from the object's plausible colour range (when not
    /// `randomized`); with neither, the renderer keeps the object's own.
    #[serde(default)]
    pub plausible: bool,
    /// The procedural model's edges rounded and its surface roughened
    /// (`[randomize.surface]`); none: the mesh as built, a smooth finish.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<ObjectSurface>,
}

/// How a procedural object's surface departs from its ideal model, as real
/// objects' do: its sharp edges rounded, and a fine relief in its shading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSurface {
    /// Radius of the rounded edges in metres (edges sharper than 30
    /// degrees; 0 keeps them sharp).
    pub edge_radius_m: f64,
    /// Strength of the relief's bump in the shading normal, 0 to 1.
    pub relief: f64,
    /// Size of the relief's features in metres.
    pub relief_size_m: f64,
}

/// The colour-management view transform and look (Blender names).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToneMapping {
    pub view_transform: String,
    pub look: String,
}

/// Environment lighting from an HDR image of Blender's bundled studio-light
/// worlds (`datafiles/studiolights/world/NAME.exr`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldLight {
    /// File stem, e.g. `city`.
    pub hdri: String,
    /// Rotation of the environment about world Z, degrees.
    pub rotation_deg: f64,
    /// Background strength (1 = the image's radiance).
    pub strength: f64,
}

/// Camera motion blur along the planned path (Cycles).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionBlur {
    /// Shutter time as a fraction of the frame interval, centred on the frame.
    pub shutter: f64,
}

/// Image-space camera effects, applied in Rust to each rendered frame in
/// this order: white balance, defocus blur, noise, JPEG round trip. The
/// stored frame is the degraded one. `None` fields are not applied.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorEffects {
    /// Seed of the per-frame noise (frame k uses a stream derived from it).
    pub seed: u64,
    /// Per-channel gains (R, G, B) in linear light.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white_balance: Option<[f64; 3]>,
    /// Gaussian defocus blur, standard deviation in pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blur_sigma_px: Option<f64>,
    /// Additive Gaussian noise, standard deviation as a fraction of full
    /// scale (per pixel and channel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_sigma: Option<f64>,
    /// JPEG quality (1-100) of a compress-decompress round trip.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jpeg_quality: Option<u8>,
}

impl SensorEffects {
    /// Whether any effect is applied.
    pub fn is_active(&self) -> bool {
        self.white_balance.is_some()
            || self.blur_sigma_px.is_some()
            || self.noise_sigma.is_some()
            || self.jpeg_quality.is_some()
    }
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
    /// View transform and look; `None`: the render config's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tone: Option<ToneMapping>,
    /// Environment lighting besides the lamps; `None`: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub world: Option<WorldLight>,
    /// `None`: no motion blur.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_blur: Option<MotionBlur>,
    /// `None`: the frames are stored as rendered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<SensorEffects>,
}
