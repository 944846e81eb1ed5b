//! A recipe: everything a model is trained with, as data. A recipe is a
//! TOML file of [`TrainConfig`] fields (`configs/recipes/*.toml`); each
//! `--set KEY=VALUE` is applied over it before it is read, so every option
//! is defined once, in `TrainConfig`, and any of them can be changed from
//! the command line without a flag of its own. The run writes the resolved
//! recipe (`OUT/config.toml`) and every checkpoint records it.

use crate::config::TrainConfig;
use crate::error::ConfigError;
use grasp_support::layers;
use std::path::Path;
use toml::Value;

/// Reads `recipe` (the defaults when None) with `sets` applied in order.
/// Errors name the file, the `--set` or the field at fault.
pub fn load(recipe: Option<&Path>, sets: &[String]) -> Result<TrainConfig, ConfigError> {
    let files: Vec<&Path> = recipe.into_iter().collect();
    let table = layers::load(&files, sets).map_err(|e| ConfigError::Layers {
        recipe: recipe.map(Path::to_path_buf),
        reason: grasp_support::error_chain(&e),
    })?;
    let source = match recipe {
        Some(path) => format!("recipe {}", path.display()),
        None => "the default recipe".to_string(),
    };
    let with_sets = if sets.is_empty() { "" } else { " with --set" };
    Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError::Fields {
            from: format!("{source}{with_sets}"),
            reason: e.to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use grasp_model::heads::HeadKind;
    use grasp_model::input::Crop;

    fn recipe(text: &str) -> tempfile::NamedTempFile {
        let file = tempfile::NamedTempFile::new().unwrap();
        std::fs::write(file.path(), text).unwrap();
        file
    }

    #[test]
    fn sets_override_the_recipe_by_dotted_key_and_toml_value() {
        let file = recipe("head = \"fc\"\ninput_size = 128\n[reader]\ndenoise = true\n");
        let sets = [
            "head=lstm",
            "reader.denoise = false",
            "reader.crop={ angle_deg = 18.3 }",
            "pooled_blocks=[7, 10]",
            "optimizer.lr=1e-3",
        ]
        .map(String::from);
        let cfg = load(Some(file.path()), &sets).unwrap();
        assert_eq!(cfg.head, HeadKind::Lstm);
        assert_eq!(cfg.input_size, 128);
        assert!(!cfg.reader.denoise);
        assert_eq!(cfg.reader.crop, Crop::AngleDeg(18.3));
        assert_eq!(cfg.pooled_blocks, vec![7, 10]);
        assert_eq!(cfg.optimizer.lr, 1e-3);
        assert_eq!(load(None, &[]).unwrap(), TrainConfig::default());
    }

    #[test]
    fn bad_recipes_and_sets_are_refused_by_name() {
        let err =
            |r: Option<&Path>, set: &str| format!("{:#}", load(r, &[set.to_string()]).unwrap_err());
        let e = err(None, "head");
        assert!(e.contains("--set head") && e.contains("KEY=VALUE"), "{e}");
        let e = err(None, "no_such_option=1");
        assert!(e.contains("no_such_option"), "{e}");
        let e = err(None, "head=sideways");
        assert!(e.contains("sideways"), "{e}");
        let e = err(None, "input_size.x=1");
        assert!(e.contains("input_size"), "{e}");
        let sized = recipe("input_size = 128\n");
        let e = err(Some(sized.path()), "input_size.x=1");
        assert!(e.contains("input_size is a value"), "{e}");
        let e = err(None, "reader..denoise=true");
        assert!(e.contains("not a key"), "{e}");
        let bad = recipe("head = [");
        let e = format!("{:#}", load(Some(bad.path()), &[]).unwrap_err());
        assert!(e.contains(&bad.path().display().to_string()), "{e}");
        let missing = Path::new("no/such/recipe.toml");
        let e = format!("{:#}", load(Some(missing), &[]).unwrap_err());
        assert!(e.contains("no/such/recipe.toml"), "{e}");
    }

    #[test]
    fn the_shipped_recipes_read() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/recipes");
        for name in ["fc", "lstm", "fc-tuned", "scratch"] {
            let path = dir.join(format!("{name}.toml"));
            let mut cfg = load(Some(&path), &[]).unwrap_or_else(|e| panic!("{name}: {e:#}"));
            cfg.data = "data".into();
            cfg.validate().unwrap_or_else(|e| panic!("{name}: {e:#}"));
        }
    }
}
