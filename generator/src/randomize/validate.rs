//! Checks of `[randomize]`, and the check that training's appearance and
//! levers never reach the `unseen_look` condition's values.

use super::{RandomizeConfig, DISTRACTOR_SHAPES, MAX_DISTRACTORS};
use crate::appearance::AppearanceConfig;
use crate::config::error::{ConfigError, Result};
use crate::look::unseen_config::{UnseenLookConfig, UNSEEN_FAMILIES, UNSEEN_LIGHT_KINDS};
use crate::look::{check_hdris, check_range};

fn check_probability(field: &str, p: f64) -> Result<()> {
    if !(0.0..=1.0).contains(&p) {
        return Err(ConfigError::invalid(
            field,
            format!("a probability must be in [0, 1], got {p}"),
        ));
    }
    Ok(())
}

impl RandomizeConfig {
    /// Checks every lever's values; errors name the `[randomize]` field.
    pub fn validate(&self) -> Result<()> {
        check_range("[randomize.fov] scale", self.fov.scale, 0.05, 20.0)?;
        let pp = self.principal_point.max_shift;
        if !(0.0..=0.25).contains(&pp) {
            return Err(ConfigError::invalid(
                "[randomize.principal_point] max_shift",
                format!("must be in [0, 0.25], got {pp}"),
            ));
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
            return Err(ConfigError::invalid(
                "[randomize.jpeg] quality",
                format!("need 1 <= min <= max <= 100, got {:?}", j.quality),
            ));
        }
        let w = &self.world_light;
        check_probability("[randomize.world_light] probability", w.probability)?;
        check_range("[randomize.world_light] strength", w.strength, 0.0, 100.0)?;
        check_hdris("[randomize.world_light] hdris", &w.hdris)?;
        let o = &self.object_color;
        if !(0.0..=0.5).contains(&o.derived_hue) {
            return Err(ConfigError::invalid(
                "[randomize.object_color] derived_hue",
                format!("must be in [0, 0.5] turns, got {}", o.derived_hue),
            ));
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
            return Err(ConfigError::invalid(
                "[randomize.distractors] count",
                format!("need min <= max <= {MAX_DISTRACTORS}, got {:?}", d.count),
            ));
        }
        check_range("[randomize.distractors] size_m", d.size_m, 0.005, 1.0)?;
        if d.shapes.is_empty() {
            return Err(ConfigError::invalid(
                "[randomize.distractors] shapes",
                "the list is empty",
            ));
        }
        for s in &d.shapes {
            ConfigError::check_one_of("[randomize.distractors] shapes", s, &DISTRACTOR_SHAPES)?;
        }
        if !(d.clearance_m.is_finite() && d.clearance_m >= 0.0) || d.attempts == 0 {
            return Err(ConfigError::rule(
                "[randomize.distractors] clearance_m",
                "must be >= 0 and attempts >= 1",
            ));
        }
        let spread = self.proportions.spread;
        if !(spread.is_finite() && (0.0..=1.0).contains(&spread)) {
            return Err(ConfigError::invalid(
                "[randomize.proportions] spread",
                format!("must be in [0, 1], got {spread}"),
            ));
        }
        let surface = &self.surface;
        check_range(
            "[randomize.surface] edge_radius_m",
            surface.edge_radius_m,
            0.0,
            0.05,
        )?;
        check_range("[randomize.surface] relief", surface.relief, 0.0, 1.0)?;
        check_range(
            "[randomize.surface] relief_size_m",
            surface.relief_size_m,
            1e-4,
            1.0,
        )?;
        check_range("[randomize.standoff] scale", self.standoff.scale, 0.0, 10.0)?;
        let a = self.aim.fraction;
        if !(0.0..=1.0).contains(&a) {
            return Err(ConfigError::invalid(
                "[randomize.aim] fraction",
                format!("must be in [0, 1], got {a}"),
            ));
        }
        Ok(())
    }
}

/// Two closed ranges share a point.
fn overlap([a0, a1]: [f64; 2], [b0, b1]: [f64; 2]) -> bool {
    a0 <= b1 && b0 <= a1
}

/// Refuses a config in which training could draw one of the `unseen_look`
/// condition's values (`unseen`): shared families, light kinds, light counts,
/// colour temperatures, HDRIs, lens factors, view transform, exposure or
/// noise levels. `render_view_transform` is `[render] view_transform`.
pub fn check_unseen_disjoint(
    unseen: &UnseenLookConfig,
    training: &AppearanceConfig,
    levers: &RandomizeConfig,
    render_view_transform: &str,
) -> Result<()> {
    let levers = &levers.effective();
    let at = "[appearance.unseen_look]";
    for f in &training.families {
        if unseen.families.contains(f) || UNSEEN_FAMILIES.contains(&f.as_str()) {
            return Err(ConfigError::invalid("[appearance] families", format!("'{f}' is reserved for the unseen_look condition and may not be drawn in training")));
        }
    }
    if unseen.families.contains(&training.held_out_family) {
        return Err(ConfigError::invalid(
            format!("{at} families"),
            format!(
                "'{}' is the background condition's held-out family",
                training.held_out_family
            ),
        ));
    }
    for k in &training.light_kinds {
        if UNSEEN_LIGHT_KINDS.contains(&k.as_str()) {
            return Err(ConfigError::invalid(
                "[appearance] light_kinds",
                format!("'{k}' is reserved for the unseen_look condition"),
            ));
        }
    }
    let unseen_count = [
        f64::from(unseen.ring_lights[0] + 1),
        f64::from(unseen.ring_lights[1] + 1),
    ];
    let training_count = training.lights.map(f64::from);
    if overlap(training_count, unseen_count) {
        return Err(ConfigError::rule("[appearance] lights", format!("{:?} overlaps the unseen_look light count {unseen_count:?} (a sun and ring_lights {:?})", training.lights, unseen.ring_lights)));
    }
    if overlap(training.color_temperature_k, unseen.color_temperature_k) {
        return Err(ConfigError::rule(at, format!("color_temperature_k {:?} overlaps training's [appearance] color_temperature_k {:?}", unseen.color_temperature_k, training.color_temperature_k)));
    }
    if levers.world_light.enabled {
        if let Some(h) = levers
            .world_light
            .hdris
            .iter()
            .find(|h| unseen.hdris.contains(h))
        {
            return Err(ConfigError::invalid(
                "[randomize.world_light] hdris",
                format!("'{h}' is also an unseen_look world ({at} hdris)"),
            ));
        }
    }
    let fov = levers.training_fov_scale();
    if overlap(fov, unseen.fov_scale) {
        return Err(ConfigError::rule(at, format!("fov_scale {:?} overlaps training's lens range {fov:?} ([randomize.fov] scale, or 1 with the lever off)", unseen.fov_scale)));
    }
    if unseen.view_transform == render_view_transform {
        return Err(ConfigError::invalid(
            format!("{at} view_transform"),
            format!(
                "'{}' is also training's [render] view_transform",
                unseen.view_transform
            ),
        ));
    }
    if overlap(training.exposure, unseen.exposure) {
        return Err(ConfigError::rule(
            at,
            format!(
                "exposure {:?} overlaps training's [appearance] exposure {:?}",
                unseen.exposure, training.exposure
            ),
        ));
    }
    if levers.sensor_noise.enabled && overlap(levers.sensor_noise.sigma, unseen.noise_sigma) {
        return Err(ConfigError::rule(
            at,
            format!(
                "noise_sigma {:?} overlaps training's [randomize.sensor_noise] sigma {:?}",
                unseen.noise_sigma, levers.sensor_noise.sigma
            ),
        ));
    }
    if unseen.blur_sigma_px[0] <= 0.0 {
        return Err(ConfigError::invalid(
            format!("{at} blur_sigma_px"),
            "must be above 0 (training has no defocus blur)",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::look::unseen_config::DEFAULT_UNSEEN_FAMILIES;

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

    #[test]
    fn defaults_are_valid_and_disjoint_from_training() {
        assert!(DEFAULT_UNSEEN_FAMILIES
            .iter()
            .all(|f| UNSEEN_FAMILIES.contains(f)));
        let a = AppearanceConfig::default();
        a.unseen_look.validate().unwrap();
        check_unseen_disjoint(&a.unseen_look, &a, &RandomizeConfig::default(), "AgX").unwrap();
    }
}
