//! Whether a finished sequence was rendered with the render settings of
//! the config at hand. Each `sequence.json` records the settings under
//! `render` ([`super::RenderConfig::blender_settings`]); a dataset that
//! mixes two settings that change pixels (a `center_region`, samples, the
//! denoiser, bounces...) is two datasets in one folder, so `render
//! --resume` refuses to add to it and `dataset verify --config` reports it.

use super::RenderConfig;
use grasp_schema::dataset::{
    CENTER_REGION_KEY, PART_LABELS_KEY, RENDER_COST_KEY, STUDIO_WORLD, WORLD_KEY,
};
use serde_json::Value;
use std::fmt;

/// Recorded keys that may differ between the sequences of one dataset:
/// where the pixels were computed (`device`, thread count), how losslessly
/// compressed PNGs are, and what the record adds to the settings (cost,
/// part names).
const MAY_DIFFER: [&str; 5] = [
    "device",
    "threads",
    "png_compression",
    RENDER_COST_KEY,
    PART_LABELS_KEY,
];

/// One `[render]` setting whose recorded value differs from the config's.
#[derive(Debug, Clone, PartialEq)]
pub struct SettingChange {
    pub field: String,
    pub recorded: Value,
    pub configured: Value,
}

impl fmt::Display for SettingChange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "[render] {}: rendered with {}, the config has {}",
            self.field, self.recorded, self.configured
        )
    }
}

/// The settings of `config` that differ from a record's `render` value.
/// A key the record lacks is compared only where its absence has a
/// meaning (`center_region`: the whole frame); otherwise the record
/// predates the setting and says nothing about it.
pub fn changed_settings(config: &RenderConfig, recorded: &Value) -> Vec<SettingChange> {
    // The same JSON round trip as the record, so floats compare exactly.
    let configured = serde_json::to_string(&config.blender_settings())
        .and_then(|t| serde_json::from_str::<Value>(&t))
        .unwrap_or_default();
    let (Some(cfg), Some(rec)) = (configured.as_object(), recorded.as_object()) else {
        return Vec::new();
    };
    let mut fields: Vec<&String> = cfg.keys().chain(rec.keys()).collect();
    fields.sort();
    fields.dedup();
    fields
        .into_iter()
        .filter(|f| !MAY_DIFFER.contains(&f.as_str()))
        .filter_map(|field| {
            let value = |m: &serde_json::Map<String, Value>| {
                m.get(field).cloned().or_else(|| implicit(field))
            };
            match (value(rec), value(cfg)) {
                (Some(recorded), Some(configured)) if recorded != configured => {
                    Some(SettingChange {
                        field: field.clone(),
                        recorded,
                        configured,
                    })
                }
                _ => None,
            }
        })
        .collect()
}

/// What an absent key means: `center_region` is recorded only when it
/// crops; a record without `world` was drawn in the studio, the only world
/// there was.
fn implicit(field: &str) -> Option<Value> {
    match field {
        CENTER_REGION_KEY => Some(Value::from(1.0)),
        WORLD_KEY => Some(Value::from(STUDIO_WORLD)),
        _ => None,
    }
}

/// `[render] a: ...; [render] b: ...` for messages.
pub fn describe(changes: &[SettingChange]) -> String {
    let each: Vec<String> = changes.iter().map(|c| c.to_string()).collect();
    each.join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Device;

    fn recorded(config: &RenderConfig) -> Value {
        let mut v = config.blender_settings();
        v[RENDER_COST_KEY] = serde_json::json!({"setup_seconds": 1.0, "device": "cpu"});
        v
    }

    #[test]
    fn the_same_settings_match_and_device_threads_compression_may_differ() {
        let config = RenderConfig {
            center_region: 0.5,
            ..Default::default()
        };
        let record = recorded(&config);
        assert_eq!(changed_settings(&config, &record), vec![]);
        let elsewhere = RenderConfig {
            device: Device::Cpu,
            threads: 3,
            png_compression: 90,
            ..config
        };
        assert_eq!(changed_settings(&elsewhere, &record), vec![]);
    }

    #[test]
    fn a_changed_center_region_names_the_field_and_both_values() {
        let whole = RenderConfig::default();
        let half = RenderConfig {
            center_region: 0.5,
            ..Default::default()
        };
        // Recorded whole frames (no key) against a config that crops, and
        // the other way round.
        for (config, record, old, new) in [
            (&half, recorded(&whole), "1.0", "0.5"),
            (&whole, recorded(&half), "0.5", "1.0"),
        ] {
            let changes = changed_settings(config, &record);
            assert_eq!(changes.len(), 1, "{changes:?}");
            let text = describe(&changes);
            assert!(text.contains("[render] center_region"), "{text}");
            assert!(
                text.contains(&format!("rendered with {old}, the config has {new}")),
                "{text}"
            );
        }
    }

    #[test]
    fn samples_and_denoiser_differ_and_unrecorded_keys_do_not() {
        let old = RenderConfig::default();
        let new = RenderConfig {
            samples: 16,
            denoiser: "none".into(),
            ..Default::default()
        };
        let fields: Vec<String> = changed_settings(&new, &recorded(&old))
            .into_iter()
            .map(|c| c.field)
            .collect();
        assert_eq!(fields, ["denoiser", "samples"]);
        // A record from before a setting existed says nothing about it.
        let mut older = recorded(&old);
        older.as_object_mut().unwrap().remove("samples");
        assert_eq!(changed_settings(&old, &older), vec![]);
        assert_eq!(changed_settings(&new, &serde_json::json!({})), vec![]);
    }

    #[test]
    fn a_foreign_world_differs_from_a_studio_record_even_an_old_one() {
        let studio = RenderConfig::default();
        let foreign = RenderConfig {
            world: crate::render::World::Foreign,
            ..Default::default()
        };
        let mut old = recorded(&studio);
        old.as_object_mut().unwrap().remove(WORLD_KEY);
        assert_eq!(changed_settings(&studio, &old), vec![]);
        for record in [old, recorded(&studio)] {
            let text = describe(&changed_settings(&foreign, &record));
            assert_eq!(
                text,
                "[render] world: rendered with \"studio\", the config has \"foreign\""
            );
        }
        assert_eq!(changed_settings(&foreign, &recorded(&foreign)), vec![]);
    }
}
