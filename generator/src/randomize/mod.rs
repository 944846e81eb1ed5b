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
//! | `object_scale` | the object's size (mesh and part boxes, uniformly) | plan, Blender, part labels |
//! | `standoff` | where the approach stops short of the target | plan |
//! | `aim` | the aim point within the target part's end face | plan |
//! | `approach_ends` | both ends of the part's approach axis, balanced | plan |
//!
//! The `unseen_look` condition takes its appearance from
//! `[appearance.unseen_look]` instead (see [`crate::unseen_look`]); of these
//! levers it keeps the geometric ones (principal point, object colour,
//! distractors, object scale, standoff, aim, approach ends).

use crate::appearance::{hsv_to_linear_rgb, AppearanceConfig};
use crate::catalog::ColorRange;
use anyhow::{bail, Result};
use grasp_schema::appearance::{Appearance, MotionBlur, SensorEffects, WorldLight};
use grasp_schema::plan::{substream_seed, CameraIntrinsics};
use grasp_schema::Condition;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// The world HDRIs shipped in the bpy wheel
/// (`bpy/5.0/datafiles/studiolights/world/*.exr`, CC0, Poly Haven).
pub const BUNDLED_HDRIS: [&str; 8] = [
    "city",
    "courtyard",
    "forest",
    "interior",
    "night",
    "studio",
    "sunrise",
    "sunset",
];

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
    pub object_scale: ObjectScaleLever,
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
            object_scale: Default::default(),
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

/// The object's size: its mesh and part boxes scaled uniformly about the
/// object frame's origin by a log-uniform factor, so that apparent size
/// stops naming the object (real ones differ from the catalog's models).
/// The plan, its validity checks and the part labels use the scaled object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObjectScaleLever {
    pub enabled: bool,
    /// Factor range; 1 is the catalog's size.
    pub scale: [f64; 2],
}

impl Default for ObjectScaleLever {
    fn default() -> Self {
        ObjectScaleLever {
            enabled: false,
            scale: [0.8, 1.25],
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

/// A `[lo, hi]` range check naming the field.
pub(crate) fn check_range(field: &str, [lo, hi]: [f64; 2], min: f64, max: f64) -> Result<()> {
    if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= min && hi <= max) {
        bail!("{field}: need a range [min, max] within [{min}, {max}], got [{lo}, {hi}]");
    }
    Ok(())
}

fn check_probability(field: &str, p: f64) -> Result<()> {
    if !(0.0..=1.0).contains(&p) {
        bail!("{field}: a probability must be in [0, 1], got {p}");
    }
    Ok(())
}

impl RandomizeConfig {
    /// Checks every lever's values; errors name the `[randomize]` field.
    pub fn validate(&self) -> Result<()> {
        check_range("[randomize.fov] scale", self.fov.scale, 0.05, 20.0)?;
        let pp = self.principal_point.max_shift;
        if !(0.0..=0.25).contains(&pp) {
            bail!("[randomize.principal_point] max_shift: must be in [0, 0.25], got {pp}");
        }
        check_range(
            "[randomize.sensor_noise] sigma",
            self.sensor_noise.sigma,
            0.0,
            0.5,
        )?;
        check_range(
            "[randomize.motion_blur] shutter",
            self.motion_blur.shutter,
            0.0,
            2.0,
        )?;
        check_range(
            "[randomize.white_balance] gain",
            self.white_balance.gain,
            0.2,
            5.0,
        )?;
        let j = &self.jpeg;
        check_probability("[randomize.jpeg] probability", j.probability)?;
        if j.quality[0] < 1 || j.quality[1] > 100 || j.quality[0] > j.quality[1] {
            bail!(
                "[randomize.jpeg] quality: need 1 <= min <= max <= 100, got {:?}",
                j.quality
            );
        }
        let w = &self.world_light;
        check_probability("[randomize.world_light] probability", w.probability)?;
        check_range("[randomize.world_light] strength", w.strength, 0.0, 100.0)?;
        check_hdris("[randomize.world_light] hdris", &w.hdris)?;
        let o = &self.object_color;
        if !(0.0..=0.5).contains(&o.derived_hue) {
            bail!(
                "[randomize.object_color] derived_hue: must be in [0, 0.5] turns, got {}",
                o.derived_hue
            );
        }
        check_range(
            "[randomize.object_color] derived_saturation",
            o.derived_saturation,
            0.0,
            10.0,
        )?;
        check_range(
            "[randomize.object_color] derived_value",
            o.derived_value,
            0.0,
            10.0,
        )?;
        let d = &self.distractors;
        if d.count[0] > d.count[1] || d.count[1] > MAX_DISTRACTORS {
            bail!(
                "[randomize.distractors] count: need min <= max <= {MAX_DISTRACTORS}, got {:?}",
                d.count
            );
        }
        check_range("[randomize.distractors] size_m", d.size_m, 0.005, 1.0)?;
        if d.shapes.is_empty() {
            bail!("[randomize.distractors] shapes: the list is empty");
        }
        for s in &d.shapes {
            if !DISTRACTOR_SHAPES.contains(&s.as_str()) {
                bail!(
                    "[randomize.distractors] shapes: unknown shape '{s}' (expected some of {})",
                    DISTRACTOR_SHAPES.join(", ")
                );
            }
        }
        if !(d.clearance_m.is_finite() && d.clearance_m >= 0.0) || d.attempts == 0 {
            bail!("[randomize.distractors] clearance_m must be >= 0 and attempts >= 1");
        }
        check_range(
            "[randomize.object_scale] scale",
            self.object_scale.scale,
            0.1,
            10.0,
        )?;
        check_range("[randomize.standoff] scale", self.standoff.scale, 0.0, 10.0)?;
        let a = self.aim.fraction;
        if !(0.0..=1.0).contains(&a) {
            bail!("[randomize.aim] fraction: must be in [0, 1], got {a}");
        }
        Ok(())
    }

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
            r.object_scale.enabled = false;
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

/// Checks a list of bundled HDRI names.
pub(crate) fn check_hdris(field: &str, hdris: &[String]) -> Result<()> {
    if hdris.is_empty() {
        bail!("{field}: the list is empty");
    }
    for h in hdris {
        if !BUNDLED_HDRIS.contains(&h.as_str()) {
            bail!(
                "{field}: '{h}' is not one of the bpy wheel's studio-light worlds ({})",
                BUNDLED_HDRIS.join(", ")
            );
        }
    }
    Ok(())
}

/// Uniform in [lo, hi) (lo for an empty range).
pub(crate) fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        rng.gen_range(lo..hi)
    } else {
        lo
    }
}

/// Log-uniform in [lo, hi] (both positive).
fn log_uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    uniform(rng, [lo.max(1e-12).ln(), hi.max(1e-12).ln()]).exp()
}

/// The RNG of one lever of one sequence.
pub fn lever_rng(stream: u64, lever: &str) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(substream_seed(stream, lever))
}

/// A sequence's object scale (1 with the lever off).
pub fn object_scale(levers: &RandomizeConfig, stream: u64) -> f64 {
    let lever = &levers.object_scale;
    if lever.enabled {
        log_uniform(&mut lever_rng(stream, "object_scale"), lever.scale)
    } else {
        1.0
    }
}

/// A sequence's camera intrinsics: the preset's lens scaled by the drawn
/// field-of-view factor, with the principal point moved. Returns the
/// intrinsics and the drawn factor and shift (fractions of the image size).
pub fn intrinsics(
    base: &CameraIntrinsics,
    fov_scale: Option<[f64; 2]>,
    principal_point: Option<f64>,
    stream: u64,
) -> (CameraIntrinsics, f64, [f64; 2]) {
    let scale = fov_scale.map_or(1.0, |r| uniform(&mut lever_rng(stream, "fov"), r));
    let shift = principal_point.map_or([0.0, 0.0], |m| {
        let mut rng = lever_rng(stream, "principal_point");
        [uniform(&mut rng, [-m, m]), uniform(&mut rng, [-m, m])]
    });
    (scaled_intrinsics(base, scale, shift), scale, shift)
}

/// `base` with tan(half FOV) multiplied by `scale` on both axes and the
/// principal point moved by `shift` (fractions of the width and height).
pub fn scaled_intrinsics(base: &CameraIntrinsics, scale: f64, shift: [f64; 2]) -> CameraIntrinsics {
    let (w, h) = (f64::from(base.width), f64::from(base.height));
    let tan_x = (base.fov_x_deg.to_radians() / 2.0).tan() * scale;
    let tan_y = (base.fov_y_deg.to_radians() / 2.0).tan() * scale;
    CameraIntrinsics {
        fx: w / 2.0 / tan_x,
        fy: h / 2.0 / tan_y,
        cx: w / 2.0 + shift[0] * w,
        cy: h / 2.0 + shift[1] * h,
        fov_x_deg: 2.0 * tan_x.atan().to_degrees(),
        fov_y_deg: 2.0 * tan_y.atan().to_degrees(),
        ..*base
    }
}

/// A colour drawn from a plausible range (linear RGB).
pub fn plausible_color(range: &ColorRange, rng: &mut ChaCha8Rng) -> [f64; 3] {
    let h = uniform(rng, range.hue).rem_euclid(1.0);
    let s = uniform(rng, range.saturation);
    let v = uniform(rng, range.value);
    hsv_to_linear_rgb(h, s, v)
}

/// The object's plausible colour range: the catalog's, else one around its
/// own colour (`own_hsv`).
pub fn color_range(
    lever: &ObjectColorLever,
    catalog: Option<&ColorRange>,
    own_hsv: [f64; 3],
) -> ColorRange {
    catalog.copied().unwrap_or_else(|| {
        ColorRange::around(
            own_hsv,
            lever.derived_hue,
            lever.derived_saturation,
            lever.derived_value,
        )
    })
}

/// Adds the training levers' appearance values to a base appearance: the
/// plausible object colour, environment light, motion blur and the sensor
/// effects (white balance, noise, JPEG). Each lever draws from its own
/// sub-stream of `stream`.
pub fn training_appearance(
    levers: &RandomizeConfig,
    mut base: Appearance,
    colors: &ColorRange,
    stream: u64,
) -> Appearance {
    apply_object_color(levers, &mut base, colors, stream);
    let w = &levers.world_light;
    if w.enabled {
        let mut rng = lever_rng(stream, "world_light");
        let on = rng.gen_bool(w.probability);
        let world = world_light(&mut rng, &w.hdris, w.strength);
        base.world = on.then_some(world);
    }
    if levers.motion_blur.enabled {
        let mut rng = lever_rng(stream, "motion_blur");
        base.motion_blur = Some(MotionBlur {
            shutter: uniform(&mut rng, levers.motion_blur.shutter),
        });
    }
    let mut sensor = SensorEffects {
        seed: substream_seed(stream, "sensor_frames"),
        white_balance: None,
        blur_sigma_px: None,
        noise_sigma: None,
        jpeg_quality: None,
    };
    if levers.white_balance.enabled {
        let mut rng = lever_rng(stream, "white_balance");
        let r = log_uniform(&mut rng, levers.white_balance.gain);
        let b = log_uniform(&mut rng, levers.white_balance.gain);
        sensor.white_balance = Some([r, 1.0, b]);
    }
    if levers.sensor_noise.enabled {
        let mut rng = lever_rng(stream, "sensor_noise");
        sensor.noise_sigma = Some(uniform(&mut rng, levers.sensor_noise.sigma));
    }
    let j = &levers.jpeg;
    if j.enabled {
        let mut rng = lever_rng(stream, "jpeg");
        let on = rng.gen_bool(j.probability);
        let q = rng.gen_range(j.quality[0]..=j.quality[1].max(j.quality[0]));
        sensor.jpeg_quality = on.then_some(q);
    }
    base.sensor = sensor.is_active().then_some(sensor);
    base
}

/// The plausible-colour lever alone (shared with `unseen_look`).
pub fn apply_object_color(
    levers: &RandomizeConfig,
    a: &mut Appearance,
    colors: &ColorRange,
    stream: u64,
) {
    if levers.object_color.enabled && !a.object.randomized {
        let mut rng = lever_rng(stream, "object_color");
        a.object.color = plausible_color(colors, &mut rng);
        a.object.plausible = true;
    }
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

/// The approach levers' values of one sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApproachDraw {
    pub standoff_m: f64,
    /// Aim offset on the end face, as fractions of the box's X and Y half
    /// extents.
    pub aim: [f64; 2],
    /// The end (+1 or -1 along the box's Z) this sequence approaches first,
    /// and for how many candidates; `None` draws the end per candidate.
    pub end: Option<(f64, u32)>,
}

/// Draws the approach levers (standoff, aim, approach end).
pub fn approach(levers: &RandomizeConfig, base_standoff_m: f64, stream: u64) -> ApproachDraw {
    let standoff_m = if levers.standoff.enabled {
        base_standoff_m * uniform(&mut lever_rng(stream, "standoff"), levers.standoff.scale)
    } else {
        base_standoff_m
    };
    let aim = if levers.aim.enabled {
        let f = levers.aim.fraction;
        let mut rng = lever_rng(stream, "aim");
        [uniform(&mut rng, [-f, f]), uniform(&mut rng, [-f, f])]
    } else {
        [0.0, 0.0]
    };
    let end = levers.approach_ends.enabled.then(|| {
        let sign = if lever_rng(stream, "approach_end").gen::<bool>() {
            1.0
        } else {
            -1.0
        };
        (sign, levers.approach_ends.forced_attempts)
    });
    ApproachDraw {
        standoff_m,
        aim,
        end,
    }
}

/// The training appearance of one sequence, or `unseen_look`'s own.
/// `center` is the object's position (the `unseen_look` lights surround it).
pub fn sequence_appearance(
    appearance: &AppearanceConfig,
    levers: &RandomizeConfig,
    condition: Condition,
    stream: u64,
    colors: &ColorRange,
    center: [f64; 3],
    images: &[String],
) -> Appearance {
    let seed = substream_seed(stream, "appearance");
    if condition == Condition::UnseenLook {
        let mut a = crate::unseen_look::sample(appearance, seed, stream, center, images);
        apply_object_color(levers, &mut a, colors, stream);
        return a;
    }
    let base = crate::appearance::sample_with_images(appearance, condition, seed, images);
    training_appearance(levers, base, colors, stream)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base_k() -> CameraIntrinsics {
        crate::plan::CameraConfig::default().intrinsics()
    }

    #[test]
    fn fov_scale_of_one_keeps_the_lens() {
        let k = base_k();
        let s = scaled_intrinsics(&k, 1.0, [0.0, 0.0]);
        assert!((s.fx - k.fx).abs() < 1e-9 && (s.fov_y_deg - k.fov_y_deg).abs() < 1e-9);
        let wide = scaled_intrinsics(&k, 1.2, [0.1, -0.05]);
        assert!(wide.fov_y_deg > k.fov_y_deg && wide.fx < k.fx);
        assert!((wide.cx - (112.0 + 22.4)).abs() < 1e-9);
        assert!((wide.cy - (112.0 - 11.2)).abs() < 1e-9);
    }

    #[test]
    fn levers_draw_from_their_own_streams() {
        let on = RandomizeConfig::default();
        let mut off = on.clone();
        off.world_light.enabled = false;
        let colors = ColorRange {
            hue: [0.1, 0.2],
            saturation: [0.5, 0.6],
            value: [0.5, 0.6],
        };
        let cfg = AppearanceConfig::default();
        for s in 0..50 {
            let a = sequence_appearance(&cfg, &on, Condition::Default, s, &colors, [0.0; 3], &[]);
            let b = sequence_appearance(&cfg, &off, Condition::Default, s, &colors, [0.0; 3], &[]);
            assert_eq!(b.world, None);
            // Only the world light differs.
            let mut a2 = a.clone();
            a2.world = None;
            assert_eq!(a2, b);
        }
    }

    #[test]
    fn bad_levers_name_their_field() {
        let mut c = RandomizeConfig::default();
        c.jpeg.quality = [90, 20];
        assert!(format!("{:#}", c.validate().unwrap_err()).contains("[randomize.jpeg] quality"));
        let mut c = RandomizeConfig::default();
        c.world_light.hdris = vec!["beach".into()];
        assert!(format!("{:#}", c.validate().unwrap_err()).contains("beach"));
        let mut c = RandomizeConfig::default();
        c.distractors.count = [0, 9];
        assert!(format!("{:#}", c.validate().unwrap_err()).contains("distractors"));
        RandomizeConfig::default().validate().unwrap();
    }
}
