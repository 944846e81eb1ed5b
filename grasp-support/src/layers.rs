//! Config files in layers: a base TOML file, files laid over it, then
//! `--set KEY=VALUE` overrides. `grasp-gen` builds a derived test set's
//! config this way (`--config configs/main.toml --config
//! configs/test-look-b.toml --set dataset.seed=3`) and `grasp-train` a
//! recipe with its overrides, so no tool rewrites TOML text.
//!
//! A later layer wins key by key: its tables merge into the earlier ones',
//! any other value (numbers, strings, arrays) replaces the earlier one.

use anyhow::{Context, Result};
use std::path::Path;
use toml::{Table, Value};

/// Reads `files` in order, each merged over the ones before, then applies
/// `sets` in order. No files and no sets give an empty table (every
/// default). Errors name the file or the `--set` at fault.
pub fn load<P: AsRef<Path>>(files: &[P], sets: &[String]) -> Result<Table> {
    let mut table = Table::new();
    for path in files {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let layer = text
            .parse::<Table>()
            .with_context(|| format!("{} is not valid TOML", path.display()))?;
        merge(&mut table, layer);
    }
    for set in sets {
        apply_set(&mut table, set).with_context(|| format!("--set {set}"))?;
    }
    Ok(table)
}

/// Where a resolved table came from, for error messages: "FILE", "FILE +
/// FILE2", with " with --set" when overrides were applied.
pub fn describe<P: AsRef<Path>>(files: &[P], sets: &[String], none: &str) -> String {
    let names: Vec<String> = files
        .iter()
        .map(|p| p.as_ref().display().to_string())
        .collect();
    let source = if names.is_empty() {
        none.to_string()
    } else {
        names.join(" + ")
    };
    if sets.is_empty() {
        source
    } else {
        format!("{source} with --set")
    }
}

/// Lays `over` onto `base`: tables merge recursively, other values replace.
pub fn merge(base: &mut Table, over: Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(Value::Table(below)), Value::Table(above)) => merge(below, above),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

/// Applies one `KEY=VALUE`: a dotted key (`dataset.seed`, `reader.denoise`)
/// and a TOML value (`0.5`, `true`, `[7, 10]`, `["fast"]`,
/// `{ angle_deg = 18.3 }`); a value that is no TOML is taken as a string
/// (`head=lstm`, `weights=path/to/file.pth`).
pub fn apply_set(table: &mut Table, set: &str) -> Result<()> {
    let (key, value) = set
        .split_once('=')
        .context("expected KEY=VALUE, e.g. --set dataset.seed=3 or --set head=lstm")?;
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

    fn file(text: &str) -> tempfile::NamedTempFile {
        let file = tempfile::NamedTempFile::new().unwrap();
        std::fs::write(file.path(), text).unwrap();
        file
    }

    #[test]
    fn later_layers_win_key_by_key_and_sets_win_last() {
        let base = file("[dataset]\nseed = 1\nsequences_per_pair = 24\n[render]\nsamples = 1\ncenter_region = 0.5\n");
        let over = file("[dataset]\nconditions = [\"unseen_look\"]\n[render]\ncenter_region = 0.7\n[appearance.unseen_look]\nfov_scale = [0.6, 0.8]\n");
        let sets = [
            "dataset.seed=3",
            "dataset.conditions=[\"fast\"]",
            "render.world = foreign",
        ]
        .map(String::from);
        let t = load(&[base.path(), over.path()], &sets).unwrap();
        let d = t["dataset"].as_table().unwrap();
        assert_eq!(d["seed"].as_integer(), Some(3));
        assert_eq!(d["sequences_per_pair"].as_integer(), Some(24));
        assert_eq!(
            d["conditions"].as_array().unwrap()[0].as_str(),
            Some("fast")
        );
        let r = t["render"].as_table().unwrap();
        assert_eq!(r["samples"].as_integer(), Some(1));
        assert_eq!(r["center_region"].as_float(), Some(0.7));
        assert_eq!(r["world"].as_str(), Some("foreign"));
        assert!(t["appearance"]["unseen_look"]["fov_scale"].is_array());
        assert!(load::<&Path>(&[], &[]).unwrap().is_empty());
    }

    #[test]
    fn bad_layers_and_sets_are_refused_by_name() {
        let err = |files: &[&Path], set: &str| {
            format!("{:#}", load(files, &[set.to_string()]).unwrap_err())
        };
        let e = err(&[], "seed");
        assert!(e.contains("--set seed") && e.contains("KEY=VALUE"), "{e}");
        let e = err(&[], "dataset..seed=1");
        assert!(e.contains("not a key"), "{e}");
        let base = file("[dataset]\nseed = 1\n");
        let e = err(&[base.path()], "dataset.seed.x=1");
        assert!(e.contains("dataset.seed is a value"), "{e}");
        let bad = file("seed = [");
        let e = format!("{:#}", load(&[bad.path()], &[]).unwrap_err());
        assert!(e.contains(&bad.path().display().to_string()), "{e}");
        let e = format!("{:#}", load(&[Path::new("no/such.toml")], &[]).unwrap_err());
        assert!(e.contains("no/such.toml"), "{e}");
        assert_eq!(describe::<&Path>(&[], &[], "the defaults"), "the defaults");
        let sets = ["a=1".to_string()];
        assert_eq!(
            describe(&[Path::new("a.toml"), Path::new("b.toml")], &sets, "x"),
            "a.toml + b.toml with --set"
        );
    }
}
