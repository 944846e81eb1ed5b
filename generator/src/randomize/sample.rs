//! The levers' draws for one sequence, each from its own named sub-stream,
//! and the sequence's appearance (training's, or `unseen_look`'s).

use super::levers::*;
use crate::appearance::{hsv_to_linear_rgb, AppearanceConfig};
use crate::catalog::ColorRange;
use crate::look::{lever_rng, uniform, world_light};
use grasp_schema::appearance::{Appearance, MotionBlur, ObjectSurface, SensorEffects};
use grasp_schema::plan::{substream_seed, CameraIntrinsics};
use grasp_schema::Condition;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Log-uniform in [lo, hi] (both positive).
fn log_uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    uniform(rng, [lo.max(1e-12).ln(), hi.max(1e-12).ln()]).exp()
}

/// A sequence's object proportions ([1, 1, 1] with the lever off): three
/// log-uniform factors, centred so that their product is 1.
pub fn proportions(levers: &RandomizeConfig, stream: u64) -> [f64; 3] {
    let lever = &levers.proportions;
    if !lever.enabled {
        return [1.0; 3];
    }
    let mut rng = lever_rng(stream, "proportions");
    let reach = (1.0 + lever.spread).ln();
    let logs: [f64; 3] = std::array::from_fn(|_| uniform(&mut rng, [-reach, reach]));
    let mean = logs.iter().sum::<f64>() / 3.0;
    logs.map(|l| (l - mean).exp())
}

/// A procedural object's surface ([`SurfaceLever`]; none with the lever
/// off): edge radius and relief strength uniform, relief size log-uniform.
pub fn object_surface(levers: &RandomizeConfig, stream: u64) -> Option<ObjectSurface> {
    let lever = &levers.surface;
    if !lever.enabled {
        return None;
    }
    let mut rng = lever_rng(stream, "surface");
    Some(ObjectSurface {
        edge_radius_m: uniform(&mut rng, lever.edge_radius_m),
        relief: uniform(&mut rng, lever.relief),
        relief_size_m: log_uniform(&mut rng, lever.relief_size_m),
    })
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
}
