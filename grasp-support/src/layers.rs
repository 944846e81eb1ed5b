//! Config files in layers: a base TOML file, files laid over it, then
//! `--set KEY=VALUE` overrides. `grasp-gen` builds a derived test set's
//! config this way (`--config configs/main.toml --config
//! configs/test-look-b.toml --set dataset.seed=3`) and `grasp-train` a
//! recipe with its overrides, so no tool rewrites TOML text.
//!
//! A later layer wins key by key: its tables merge into the earlier ones',
//! any other value (numbers, strings, arrays) replaces the earlier one.

use std::path::{Path, PathBuf};
use toml::{Table, Value};

/// A layer that cannot be read: the file or the `--set` at fault.
#[derive(Debug, thiserror::Error)]
pub enum LayersError {
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{} is not valid TOML", path.display())]
    Toml {
        path: PathBuf,
        #[source]
        source: toml::de::Error,
    },
    #[error("--set {set}")]
    Set {
        set: String,
        #[source]
        source: SetError,
    },
}

/// Why one `--set KEY=VALUE` cannot be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SetError {
    #[error("expected KEY=VALUE, e.g. --set dataset.seed=3 or --set head=lstm")]
    NoValue,
    #[error("'{0}' is not a key")]
    NotAKey(String),
    #[error("{0} is a value, not a table")]
    NotATable(String),
}

/// Reads `files` in order, each merged over the ones before, then applies
/// `sets` in order. No files and no sets give an empty table (every
/// default). Errors name the file or the `--set` at fault.
pub fn load<P: AsRef<Path>>(files: &[P], sets: &[String]) -> Result<Table, LayersError> {
    let mut table = Table::new();
    for path in files {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| LayersError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let layer = text.parse::<Table>().map_err(|source| LayersError::Toml {
            path: path.to_path_buf(),
            source,
        })?;
        merge(&mut table, layer);
    }
    for set in sets {
        apply_set(&mut table, set).map_err(|source| LayersError::Set {
            set: set.clone(),
            source,
        })?;
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
pub fn apply_set(table: &mut Table, set: &str) -> Result<(), SetError> {
    let (key, value) = set.split_once('=').ok_or(SetError::NoValue)?;
    let path: Vec<&str> = key.trim().split('.').map(str::trim).collect();
    let not_a_key = || SetError::NotAKey(key.trim().to_string());
    if path.iter().any(|p| p.is_empty()) {
        return Err(not_a_key());
    }
    let (last, parents) = path.split_last().ok_or_else(not_a_key)?;
    let mut at = table;
    for (depth, part) in parents.iter().enumerate() {
        let entry = at
            .entry(part.to_string())
            .or_insert_with(|| Value::Table(Table::new()));
        at = entry
            .as_table_mut()
            .ok_or_else(|| SetError::NotATable(path[..=depth].join(".")))?;
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
            crate::error_chain(&load(files, &[set.to_string()]).unwrap_err())
        };
        let e = err(&[], "seed");
        assert!(e.contains("--set seed") && e.contains("KEY=VALUE"), "{e}");
        let e = err(&[], "dataset..seed=1");
        assert!(e.contains("not a key"), "{e}");
        let base = file("[dataset]\nseed = 1\n");
        let e = err(&[base.path()], "dataset.seed.x=1");
        assert!(e.contains("dataset.seed is a value"), "{e}");
        let bad = file("seed = [");
        let e = crate::error_chain(&load(&[bad.path()], &[]).unwrap_err());
        assert!(e.contains(&bad.path().display().to_string()), "{e}");
        let e = crate::error_chain(&load(&[Path::new("no/such.toml")], &[]).unwrap_err());
        assert!(e.contains("no/such.toml"), "{e}");
        assert_eq!(describe::<&Path>(&[], &[], "the defaults"), "the defaults");
        let sets = ["a=1".to_string()];
        assert_eq!(
            describe(&[Path::new("a.toml"), Path::new("b.toml")], &sets, "x"),
            "a.toml + b.toml with --set"
        );
    }
}
