//! The lever config types of `[randomize]`, their defaults and how they act
//! with the master switch.

use serde::{Deserialize, Serialize};

/// Distractor shapes the Blender side builds.
pub const DISTRACTOR_SHAPES: [&str; 3] = ["box", "cylinder", "sphere"];
/// Distractor objects the Blender side pools.
pub const MAX_DISTRACTORS: u32 = 6;

/// Every lever (`[randomize]` in the config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RandomizeConfig {
    /// `false` turns every lever off at once (the randomisation before these
    /// levers existed, e.g. for the authors' set-up); each lever's own
    /// `enabled` applies only while this is on.
    pub enabled: bool,
    pub fov: FovLever,
    pub principal_point: PrincipalPointLever,
    pub sensor_noise: SensorNoiseLever,
    pub motion_blur: MotionBlurLever,
    pub white_balance: WhiteBalanceLever,
    pub jpeg: JpegLever,
    pub world_light: WorldLightLever,
    pub object_color: ObjectColorLever,
    pub distractors: DistractorLever,
    pub proportions: ProportionsLever,
    pub surface: SurfaceLever,
    pub standoff: StandoffLever,
    pub aim: AimLever,
    pub approach_ends: ApproachEndsLever,
}

impl Default for RandomizeConfig {
    fn default() -> Self {
        RandomizeConfig {
            enabled: true,
            fov: Default::default(),
            principal_point: Default::default(),
            sensor_noise: Default::default(),
            motion_blur: Default::default(),
            white_balance: Default::default(),
            jpeg: Default::default(),
            world_light: Default::default(),
            object_color: Default::default(),
            distractors: Default::default(),
            proportions: Default::default(),
            surface: Default::default(),
            standoff: Default::default(),
            aim: Default::default(),
            approach_ends: Default::default(),
        }
    }
}

/// The lens: tan(half field of view) of the camera preset times a factor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FovLever {
    pub enabled: bool,
    /// Factor range; 1 is the preset's lens, below 1 zooms in.
    pub scale: [f64; 2],
}

impl Default for FovLever {
    fn default() -> Self {
        // d435 at 224 x 224: 36 to 49.5 degrees around the preset's 42.
        FovLever {
            enabled: true,
            scale: [0.85, 1.2],
        }
    }
}

/// The principal point moves off the image centre (a decentred lens).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PrincipalPointLever {
    pub enabled: bool,
    /// Largest offset along each image axis, as a fraction of the image size.
    pub max_shift: f64,
}

impl Default for PrincipalPointLever {
    fn default() -> Self {
        PrincipalPointLever {
            enabled: true,
            max_shift: 0.03,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorNoiseLever {
    pub enabled: bool,
    /// Standard deviation range of the per-pixel Gaussian noise, as a
    /// fraction of full scale (0.02 is about 5 grey levels).
    pub sigma: [f64; 2],
}

impl Default for SensorNoiseLever {
    fn default() -> Self {
        SensorNoiseLever {
            enabled: true,
            sigma: [0.0, 0.02],
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionBlurLever {
    pub enabled: bool,
    /// Shutter range, as a fraction of the frame interval.
    pub shutter: [f64; 2],
}

impl Default for MotionBlurLever {
    fn default() -> Self {
        MotionBlurLever {
            enabled: true,
            shutter: [0.2, 0.8],
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WhiteBalanceLever {
    pub enabled: bool,
    /// Range of the red and blue gains relative to green (log-uniform), in
    /// linear light: a camera's white balance set for another light.
    pub gain: [f64; 2],
}

impl Default for WhiteBalanceLever {
    fn default() -> Self {
        WhiteBalanceLever {
            enabled: true,
            gain: [0.85, 1.18],
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JpegLever {
    pub enabled: bool,
    /// Chance that a sequence's frames go through JPEG.
    pub probability: f64,
    /// Quality range (1-100), inclusive.
    pub quality: [u8; 2],
}

impl Default for JpegLever {
    fn default() -> Self {
        JpegLever {
            enabled: true,
            probability: 0.5,
            quality: [40, 95],
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WorldLightLever {
    pub enabled: bool,
    /// Chance that a sequence has environment light besides its lamps.
    pub probability: f64,
    /// Names of bundled studio-light worlds drawn from (two more,
    /// `courtyard` and `forest`, are the `unseen_look` condition's).
    pub hdris: Vec<String>,
    pub strength: [f64; 2],
}

impl Default for WorldLightLever {
    fn default() -> Self {
        WorldLightLever {
            enabled: true,
            probability: 0.6,
            hdris: ["city", "interior", "night", "studio", "sunrise", "sunset"]
                .map(String::from)
                .to_vec(),
            strength: [0.3, 1.5],
        }
    }
}

/// Objects that keep their material get a colour from their plausible range
/// (the catalog's `color`, or else one derived from their own colour)
/// instead of one fixed colour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObjectColorLever {
    pub enabled: bool,
    /// Derived range for objects without a catalog `color`: hue +- this
    /// (turns), saturation and value scaled by these factors.
    pub derived_hue: f64,
    pub derived_saturation: [f64; 2],
    pub derived_value: [f64; 2],
}

impl Default for ObjectColorLever {
    fn default() -> Self {
        ObjectColorLever {
            enabled: true,
            derived_hue: 0.04,
            derived_saturation: [0.75, 1.25],
            derived_value: [0.7, 1.25],
        }
    }
}

/// Primitives on the table that are never the target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DistractorLever {
    pub enabled: bool,
    /// Number of distractors (inclusive range, at most 6).
    pub count: [u32; 2],
    /// Edge length / diameter range, metres.
    pub size_m: [f64; 2],
    /// Some of `box`, `cylinder`, `sphere`.
    pub shapes: Vec<String>,
    /// Least gap to the target object, to the reach and to each other, metres.
    pub clearance_m: f64,
    /// Draws per distractor before it is left out.
    pub attempts: u32,
}

impl Default for DistractorLever {
    fn default() -> Self {
        DistractorLever {
            enabled: true,
            count: [0, 3],
            size_m: [0.03, 0.12],
            shapes: DISTRACTOR_SHAPES.map(String::from).to_vec(),
            clearance_m: 0.05,
            attempts: 30,
        }
    }
}

/// The object's proportions: its mesh and part boxes stretched along the
/// object frame's X, Y and Z by factors whose product is 1, so that a
/// family's real members (a taller mug, a slimmer bottle) are not all one
/// model while its size still says what it is. Each axis draws a log-factor
/// in +-ln(1 + `spread`), then the three are centred. The plan, its
/// validity checks and the part labels use the stretched object. Only the
/// project's procedural models are stretched: a mesh from a file (a real
/// object) keeps its own proportions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProportionsLever {
    pub enabled: bool,
    /// How far one axis may stretch before centring (0.15: x 0.87-1.15).
    pub spread: f64,
}

impl Default for ProportionsLever {
    fn default() -> Self {
        ProportionsLever {
            enabled: true,
            spread: 0.15,
        }
    }
}

/// The procedural object's surface: its sharp edges rounded and a fine
/// relief in its shading, as real objects are worn, moulded or scanned,
/// where the models are ideal. Rendering alone: the plan's geometry and the
/// part labels keep the model (the rounding is a few millimetres). A mesh
/// from a file keeps its own surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SurfaceLever {
    pub enabled: bool,
    /// Radius of the rounded edges in metres.
    pub edge_radius_m: [f64; 2],
    /// Strength of the relief's bump, 0 (smooth) to 1.
    pub relief: [f64; 2],
    /// Size of the relief's features in metres (log-uniform).
    pub relief_size_m: [f64; 2],
}

impl Default for SurfaceLever {
    fn default() -> Self {
        SurfaceLever {
            enabled: true,
            edge_radius_m: [0.0, 0.004],
            relief: [0.0, 0.3],
            relief_size_m: [0.002, 0.02],
        }
    }
}

/// The standoff (`plan.trajectory.standoff_m`) times a factor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StandoffLever {
    pub enabled: bool,
    pub scale: [f64; 2],
}

impl Default for StandoffLever {
    fn default() -> Self {
        // The default 0.12 m becomes 0.09 to 0.15 m: where a wrist camera
        // stops depends on the hand and the grasp.
        StandoffLever {
            enabled: true,
            scale: [0.75, 1.25],
        }
    }
}

/// The aim point moves within the end face of the target part's box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AimLever {
    pub enabled: bool,
    /// Largest offset from the face centre along the box's X and Y, as a
    /// fraction of the half extents (1 reaches the face's edges).
    pub fraction: f64,
}

impl Default for AimLever {
    fn default() -> Self {
        AimLever {
            enabled: true,
            fraction: 0.8,
        }
    }
}

/// Each sequence approaches the end of the part's approach axis chosen by a
/// fair coin, so both ends are covered even where the geometry favours one;
/// when that end admits no valid reach within `forced_attempts` candidates
/// the search falls back to both ends (recorded).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ApproachEndsLever {
    pub enabled: bool,
    pub forced_attempts: u32,
}

impl Default for ApproachEndsLever {
    fn default() -> Self {
        ApproachEndsLever {
            enabled: true,
            forced_attempts: 200,
        }
    }
}

impl RandomizeConfig {
    /// The levers as they act: every one off when `enabled` is false.
    pub fn effective(&self) -> RandomizeConfig {
        let mut r = self.clone();
        if !r.enabled {
            r.fov.enabled = false;
            r.principal_point.enabled = false;
            r.sensor_noise.enabled = false;
            r.motion_blur.enabled = false;
            r.white_balance.enabled = false;
            r.jpeg.enabled = false;
            r.world_light.enabled = false;
            r.object_color.enabled = false;
            r.distractors.enabled = false;
            r.proportions.enabled = false;
            r.surface.enabled = false;
            r.standoff.enabled = false;
            r.aim.enabled = false;
            r.approach_ends.enabled = false;
        }
        r
    }

    /// The field-of-view scale range training draws from (`[1, 1]` with the
    /// lever off).
    pub fn training_fov_scale(&self) -> [f64; 2] {
        if self.enabled && self.fov.enabled {
            self.fov.scale
        } else {
            [1.0, 1.0]
        }
    }
}
