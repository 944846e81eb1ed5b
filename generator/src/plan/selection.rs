//! Checks what `[dataset]` selects against the catalog before anything is
//! planned or rendered: a typo in `objects` or `parts` would otherwise
//! quietly select fewer sequences, or none.

use super::error::{PlanError, Result};
use super::DatasetConfig;
use crate::catalog::{Catalog, GraspPart, ObjectSpec};

/// Fails naming every unknown object id or part name (with near matches),
/// or when the selection is empty.
pub fn check_selection(d: &DatasetConfig, catalog: &Catalog) -> Result<()> {
    let ids: Vec<&str> = catalog.objects.iter().map(|o| o.id.as_str()).collect();
    let mut problems = Vec::new();
    for id in d.objects.iter().flatten() {
        if catalog.object(id).is_none() {
            problems.push(format!(
                "dataset.objects: unknown object id '{id}'{}",
                suggestion(id, &ids)
            ));
        }
    }
    let mut part_names: Vec<String> = Vec::new();
    for o in &catalog.objects {
        for p in &o.parts {
            part_names.push(p.name.clone());
            part_names.push(format!("{}/{}", o.id, p.name));
        }
    }
    part_names.sort();
    part_names.dedup();
    let names: Vec<&str> = part_names.iter().map(String::as_str).collect();
    for name in d.parts.iter().flatten() {
        if !names.contains(&name.as_str()) {
            problems.push(format!(
                "dataset.parts: no part '{name}' in the catalog{}",
                suggestion(name, &names)
            ));
        }
    }
    if !problems.is_empty() {
        return Err(PlanError::Selection {
            problems,
            catalog: catalog.dir.clone(),
            objects: ids.iter().map(|id| id.to_string()).collect(),
        });
    }
    if d.sequences_per_pair == 0 || d.conditions.is_empty() {
        return Err(PlanError::NothingSelected {
            reason: "the config selects no sequences: dataset.sequences_per_pair and \
                     dataset.conditions must not be 0 or empty",
        });
    }
    if selected_pairs(d, catalog).is_empty() {
        return Err(PlanError::NothingSelected {
            reason: "the config selects no (object, part) pair: no part named in dataset.parts \
                     belongs to an object of dataset.objects",
        });
    }
    Ok(())
}

/// The number of (object, part) pairs the config selects.
pub fn pair_count(d: &DatasetConfig, catalog: &Catalog) -> usize {
    selected_pairs(d, catalog).len()
}

/// The catalog's (object, part) pairs that pass the dataset filters.
pub fn selected_pairs<'a>(
    d: &DatasetConfig,
    catalog: &'a Catalog,
) -> Vec<(&'a ObjectSpec, &'a GraspPart)> {
    catalog
        .pairs()
        .into_iter()
        .filter_map(|(id, index)| {
            let object = catalog.object(&id)?;
            Some((object, object.parts.get(index)?))
        })
        .filter(|(o, _)| d.objects.as_ref().is_none_or(|ids| ids.contains(&o.id)))
        .filter(|(o, p)| {
            d.parts.as_ref().is_none_or(|names| {
                names
                    .iter()
                    .any(|n| *n == p.name || *n == format!("{}/{}", o.id, p.name))
            })
        })
        .collect()
}

/// ` (did you mean 'a' or 'b'?)` for the closest candidates, else empty.
fn suggestion(wrong: &str, candidates: &[&str]) -> String {
    let w = wrong.to_lowercase();
    let mut near: Vec<(usize, &str)> = candidates
        .iter()
        .map(|c| (edit_distance(&w, &c.to_lowercase()), *c))
        .filter(|(d, c)| {
            *d <= (wrong.chars().count() / 3).max(2)
                || (w.len() >= 3 && c.to_lowercase().contains(&w))
        })
        .collect();
    near.sort();
    let near: Vec<String> = near.iter().take(3).map(|(_, c)| format!("'{c}'")).collect();
    match near.len() {
        0 => String::new(),
        _ => format!(" (did you mean {}?)", near.join(" or ")),
    }
}

/// Levenshtein distance over characters (two rows).
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut row = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let substitute = prev[j] + usize::from(ca != *cb);
            row[j + 1] = substitute.min(prev[j + 1] + 1).min(row[j] + 1);
        }
        prev = row;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance_counts_edits() {
        assert_eq!(edit_distance("025_mug", "025_mug"), 0);
        assert_eq!(edit_distance("025_mugg", "025_mug"), 1);
        assert_eq!(edit_distance("052_mug", "025_mug"), 2);
        assert_eq!(edit_distance("", "abc"), 3);
    }

    #[test]
    fn near_matches_are_suggested() {
        let ids = ["025_mug", "024_bowl", "011_banana"];
        assert_eq!(suggestion("025_mugg", &ids), " (did you mean '025_mug'?)");
        assert_eq!(suggestion("banana", &ids), " (did you mean '011_banana'?)");
        assert_eq!(suggestion("xyzzy_q", &ids), "");
    }
}
