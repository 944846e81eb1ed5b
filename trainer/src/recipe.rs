//! A recipe: everything a model is trained with, as data. A recipe is a
//! TOML file of [`TrainConfig`] fields (`configs/recipes/*.toml`); each
//! `--set KEY=VALUE` is applied over it before it is read, so every option
//! is defined once, in `TrainConfig`, and any of them can be changed from
//! the command line without a flag of its own. The run writes the resolved
//! recipe (`OUT/config.toml`) and every checkpoint records it.

use crate::config::TrainConfig;
use anyhow::{Context, Result};
use std::path::Path;
use toml::{Table, Value};

/// Reads `recipe` (the defaults when None) with `sets` applied in order.
/// Errors name the file, the `--set` or the field at fault.
pub fn load(recipe: Option<&Path>, sets: &[String]) -> Result<TrainConfig> {
    let mut table = match recipe {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read recipe {}", path.display()))?;
            text.parse::<Table>()
                .with_context(|| format!("recipe {} is not valid TOML", path.display()))?
        }
        None => Table::new(),
    };
    for set in sets {
        apply(&mut table, set).with_context(|| format!("--set {set}"))?;
    }
    let source = match recipe {
        Some(path) => format!("recipe {}", path.display()),
        None => "the default recipe".to_string(),
    };
    let with_sets = if sets.is_empty() { "" } else { " with --set" };
    Value::Table(table)
        .try_into()
        .with_context(|| format!("{source}{with_sets}"))
}

/// Applies one `KEY=VALUE`: a dotted key (`reader.denoise`,
/// `optimizer.lr`) and a TOML value (`0.5`, `true`, `[7, 10]`,
/// `{ angle_deg = 18.3 }`); a value that is no TOML is taken as a string
/// (`head=lstm`, `weights=path/to/file.pth`).
fn apply(table: &mut Table, set: &str) -> Result<()> {
    let (key, value) = set
        .split_once('=')
        .context("expected KEY=VALUE, e.g. --set head=lstm or --set reader.denoise=false")?;
    let path: Vec<&str> = key.trim().split('.').map(str::trim).collect();
    anyhow::ensure!(
        path.iter().all(|p| !p.is_empty()),
        "'{}' is not a key",
        key.trim()
    );
    let (last, parents) = path.split_last().context("empty key")?;
    let mut at = table;
    for (depth, part) in parents.iter().enumerate() {
        let entry = at
            .entry(part.to_string())
            .or_insert_with(|| Value::Table(Table::new()));
        at = entry
            .as_table_mut()
            .with_context(|| format!("{} is a value, not a table", path[..=depth].join(".")))?;
    }
    at.insert(last.to_string(), parse_value(value.trim()));
    Ok(())
}

fn parse_value(text: &str) -> Value {
    format!("v = {text}")
        .parse::<Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| Value::String(text.to_string()))
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
