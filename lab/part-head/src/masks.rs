//! Each cell's part, from the generator's `part` pass: the share of the
//! cell's pixels showing each pre-shape's parts, the rest "no part".

use anyhow::{bail, Context, Result};
use generator::catalog::Catalog;
use grasp_schema::dataset::{part_file_name, SequenceRecord};
use grasp_schema::taxonomy::Class;
use std::path::Path;
use trainer::data::Sequence;

/// Cell classes: the five frame classes, then "no part".
pub const K: usize = Class::COUNT + 1;
pub const NO_PART: usize = Class::COUNT;

/// Soft cell labels of every frame of `seq`, (frames x cells x K), read
/// from the mask render at `masks` (the same folder layout as `data`).
pub fn cell_labels(
    seq: &Sequence,
    data: &Path,
    masks: &Path,
    catalog: &Catalog,
    grid: usize,
) -> Result<Vec<f32>> {
    let rel = seq
        .dir
        .strip_prefix(data)
        .context("sequence outside its dataset")?;
    let dir = masks.join(rel);
    let json = dir.join("sequence.json");
    let text = std::fs::read_to_string(&json).with_context(|| json.display().to_string())?;
    let record: SequenceRecord =
        serde_json::from_str(&text).with_context(|| json.display().to_string())?;
    let names = record
        .part_labels()
        .context("no part pass in the mask render")?;
    let object = catalog
        .object(&seq.object)
        .context("object not in the catalog")?;
    let mut class_of = vec![NO_PART];
    for name in &names {
        let part = object.part(name).with_context(|| format!("part {name}"))?;
        class_of.push(Class::from(part.grasp_type.preshape()).index());
    }
    let mut out = Vec::with_capacity(seq.frames.len() * grid * grid * K);
    for (i, frame) in seq.frames.iter().enumerate() {
        if seq.labels[i] == Class::NoGrasp {
            for _ in 0..grid * grid {
                out.extend((0..K).map(|k| {
                    if k == Class::NoGrasp.index() {
                        1.0
                    } else {
                        0.0
                    }
                }));
            }
            continue;
        }
        let file = frame
            .file_name()
            .and_then(|f| f.to_str())
            .context("frame name")?;
        let path = dir.join(part_file_name(file));
        let mask = image::open(&path)
            .with_context(|| path.display().to_string())?
            .to_luma8();
        out.extend(cells_of(&mask, seq, grid, &class_of)?);
    }
    Ok(out)
}

/// One frame's cell shares over the crop the backbone sees.
fn cells_of(
    mask: &image::GrayImage,
    seq: &Sequence,
    grid: usize,
    class_of: &[usize],
) -> Result<Vec<f32>> {
    // The crop's fraction follows from the rendered frames' own size (the
    // mask is the same view at a lower resolution).
    let (w, h) = (224, 224);
    let fraction = seq
        .crop
        .fraction(seq.lens.as_ref(), w, h)?
        .unwrap_or(1.0)
        .min(1.0);
    let (mw, mh) = mask.dimensions();
    let side = f64::from(mw.min(mh)) * fraction;
    let (x0, y0) = (
        f64::from(mw) / 2.0 - side / 2.0,
        f64::from(mh) / 2.0 - side / 2.0,
    );
    let cell = side / grid as f64;
    let mut out = vec![0f32; grid * grid * K];
    for y in 0..mh {
        for x in 0..mw {
            let (cx, cy) = (
                (f64::from(x) + 0.5 - x0) / cell,
                (f64::from(y) + 0.5 - y0) / cell,
            );
            if !(0.0..grid as f64).contains(&cx) || !(0.0..grid as f64).contains(&cy) {
                continue;
            }
            let label = mask.get_pixel(x, y).0[0] as usize;
            let Some(&k) = class_of.get(label) else {
                bail!("label {label} beyond the {} parts", class_of.len() - 1);
            };
            out[(cy as usize * grid + cx as usize) * K + k] += 1.0;
        }
    }
    for c in out.chunks_mut(K) {
        let total: f32 = c.iter().sum();
        if total == 0.0 {
            c[NO_PART] = 1.0;
        } else {
            c.iter_mut().for_each(|v| *v /= total);
        }
    }
    Ok(out)
}
