//! `grasp-gen preview DIR --out DIR`: a contact sheet (PNG) and an animated
//! GIF of a few sequences, so a person can look at the data.
//!
//! Contact sheet: one row per sequence, evenly spaced frames across the
//! reach; under each frame a strip in the colour of its label (legend in
//! `contact_sheet.txt`, with the sequence of each row).

use anyhow::{bail, Context, Result};
use generator::dataset::writer::{read_record, sequence_dirs};
use grasp_schema::dataset::{SequenceRecord, SEQUENCE_FILE};
use grasp_schema::Class;
use image::codecs::gif::{GifEncoder, Repeat};
use image::imageops::FilterType;
use image::{Delay, Frame, Rgba, RgbaImage};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone)]
pub struct PreviewOptions {
    /// Sequences on the sheet (evenly spaced through the dataset).
    pub sequences: usize,
    /// Frames per sequence on the sheet.
    pub columns: usize,
    /// Thumbnail width and height, pixels.
    pub thumb: u32,
    /// Sequences tiled side by side in the GIF.
    pub gif_sequences: usize,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            sequences: 8,
            columns: 8,
            thumb: 112,
            gif_sequences: 4,
        }
    }
}

const STRIP: u32 = 6;
const GAP: u32 = 2;

/// Colour of each class on the sheet.
pub fn class_color(class: Class) -> Rgba<u8> {
    match class {
        Class::Power => Rgba([230, 60, 50, 255]),
        Class::Lateral => Rgba([60, 160, 230, 255]),
        Class::Pinch => Rgba([80, 200, 90, 255]),
        Class::Pinch3 => Rgba([240, 190, 40, 255]),
        Class::NoGrasp => Rgba([140, 140, 140, 255]),
    }
}

/// Writes `contact_sheet.png`, `contact_sheet.txt` and `preview.gif` into
/// `out`; returns their paths.
pub fn preview(dataset: &Path, out: &Path, opts: &PreviewOptions) -> Result<Vec<PathBuf>> {
    // Folder names only; the records of the shown sequences are read.
    let dirs = sequence_dirs(dataset, false)?;
    if dirs.is_empty() {
        bail!("{}: no finished sequences to preview", dataset.display());
    }
    let load = |n: usize| -> Result<Vec<(String, SequenceRecord)>> {
        evenly(&dirs, n)
            .into_iter()
            .map(|rel| {
                Ok((
                    rel.clone(),
                    read_record(&dataset.join(rel).join(SEQUENCE_FILE))?,
                ))
            })
            .collect()
    };
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let sheet_records = load(opts.sequences)?;
    let chosen: Vec<&(String, SequenceRecord)> = sheet_records.iter().collect();
    let (sheet, legend) = contact_sheet(dataset, &chosen, opts)?;
    let sheet_path = out.join("contact_sheet.png");
    grasp_support::atomic::write_atomic_with(&sheet_path, |tmp| -> Result<()> {
        sheet
            .save_with_format(tmp, image::ImageFormat::Png)
            .with_context(|| format!("cannot write {}", sheet_path.display()))
    })?;
    let legend_path = out.join("contact_sheet.txt");
    grasp_support::atomic::write_atomic(&legend_path, legend.as_bytes())?;
    let gif_path = out.join("preview.gif");
    let gif_records = load(opts.gif_sequences)?;
    let chosen: Vec<&(String, SequenceRecord)> = gif_records.iter().collect();
    write_gif(dataset, &chosen, opts, &gif_path)?;
    Ok(vec![sheet_path, legend_path, gif_path])
}

fn evenly<T>(items: &[T], n: usize) -> Vec<&T> {
    let n = n.min(items.len()).max(1);
    (0..n).map(|i| &items[i * items.len() / n]).collect()
}

/// A frame as a `size` x `size` thumbnail: only its rendered centre when
/// the sequence was rendered with `center_region` below 1 (the rest is
/// black).
fn thumb(
    dataset: &Path,
    rel: &str,
    record: &SequenceRecord,
    frame: usize,
    size: u32,
) -> Result<RgbaImage> {
    let path = dataset.join(rel).join(&record.frame_files[frame]);
    let img =
        image::open(&path).with_context(|| format!("cannot read frame {}", path.display()))?;
    let region = record.center_region().unwrap_or(1.0);
    Ok(rendered_centre(&img, region)
        .resize_exact(size, size, FilterType::Triangle)
        .to_rgba8())
}

/// The centred square of side `region` times the shorter side: what a
/// `center_region` render drew.
fn rendered_centre(img: &image::DynamicImage, region: f64) -> image::DynamicImage {
    let (x, y, side) = grasp_schema::dataset::centre_square(img.width(), img.height(), region);
    img.crop_imm(x, y, side, side)
}

fn contact_sheet(
    dataset: &Path,
    chosen: &[&(String, SequenceRecord)],
    opts: &PreviewOptions,
) -> Result<(RgbaImage, String)> {
    let longest = chosen
        .iter()
        .map(|(_, r)| r.frame_files.len())
        .max()
        .unwrap_or(1);
    let cols = opts.columns.clamp(1, longest.max(1)) as u32;
    let cell_w = opts.thumb + GAP;
    let cell_h = opts.thumb + STRIP + GAP;
    let mut sheet = RgbaImage::from_pixel(
        cols * cell_w,
        chosen.len() as u32 * cell_h,
        Rgba([20, 20, 20, 255]),
    );
    let mut legend = String::from("rows, top to bottom:\n");
    for (row, (rel, record)) in chosen.iter().enumerate() {
        let _ = writeln!(legend, "{row}: {} ({rel})", record.plan.key.id());
        let n = record.frame_files.len();
        for col in 0..(cols as usize).min(n) {
            let f = if cols == 1 {
                n - 1
            } else {
                col * (n - 1) / (cols as usize - 1)
            };
            let img = thumb(dataset, rel, record, f, opts.thumb)?;
            let (x, y) = (col as u32 * cell_w, row as u32 * cell_h);
            image::imageops::overlay(&mut sheet, &img, x.into(), y.into());
            let color = class_color(record.plan.frames[f].class);
            for dy in 0..STRIP {
                for dx in 0..opts.thumb {
                    sheet.put_pixel(x + dx, y + opts.thumb + dy, color);
                }
            }
        }
    }
    legend.push_str(
        "label strip colours: power red, lateral blue, pinch green, pinch3 yellow, no_grasp grey\n",
    );
    Ok((sheet, legend))
}

fn write_gif(
    dataset: &Path,
    chosen: &[&(String, SequenceRecord)],
    opts: &PreviewOptions,
    path: &Path,
) -> Result<()> {
    let longest = chosen
        .iter()
        .map(|(_, r)| r.frame_files.len())
        .max()
        .unwrap_or(0);
    let fps = chosen
        .first()
        .map(|(_, r)| r.plan.fps)
        .unwrap_or(10.0)
        .clamp(1.0, 50.0);
    let mut file = grasp_support::atomic::AtomicFile::create(path)?;
    let mut enc = GifEncoder::new_with_speed(&mut file, 10);
    enc.set_repeat(Repeat::Infinite)?;
    let w = chosen.len() as u32 * (opts.thumb + GAP);
    for f in 0..longest {
        let mut canvas = RgbaImage::from_pixel(w, opts.thumb + STRIP, Rgba([20, 20, 20, 255]));
        for (i, (rel, record)) in chosen.iter().enumerate() {
            let k = f.min(record.frame_files.len() - 1);
            let img = thumb(dataset, rel, record, k, opts.thumb)?;
            let x = i as u32 * (opts.thumb + GAP);
            image::imageops::overlay(&mut canvas, &img, x.into(), 0);
            let color = class_color(record.plan.frames[k].class);
            for dy in 0..STRIP {
                for dx in 0..opts.thumb {
                    canvas.put_pixel(x + dx, opts.thumb + dy, color);
                }
            }
        }
        let delay = Delay::from_numer_denom_ms(1000, fps.round() as u32);
        enc.encode_frame(Frame::from_parts(canvas, 0, 0, delay))?;
    }
    drop(enc);
    file.commit()?;
    Ok(())
}

/// `grasp-gen preview DIR --out DIR`.
#[derive(Debug, clap::Args)]
pub struct PreviewArgs {
    /// Dataset root.
    pub dir: PathBuf,
    /// Where to write contact_sheet.png, contact_sheet.txt and preview.gif.
    #[arg(long)]
    pub out: PathBuf,
    /// Sequences on the contact sheet.
    #[arg(long, default_value_t = 8)]
    pub sequences: usize,
    /// Frames per sequence on the contact sheet.
    #[arg(long, default_value_t = 8)]
    pub columns: usize,
}

pub fn run(args: &PreviewArgs) -> Result<()> {
    let opts = PreviewOptions {
        sequences: args.sequences,
        columns: args.columns,
        ..Default::default()
    };
    for p in preview(&args.dir, &args.out, &opts)? {
        println!("wrote {}", p.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thumbnails_show_only_the_rendered_centre() {
        // 40 x 20, black but for the central 10 x 10 (region 0.5 of 20).
        let img = image::RgbImage::from_fn(40, 20, |x, y| {
            let inside = (15..25).contains(&x) && (5..15).contains(&y);
            image::Rgb(if inside { [255; 3] } else { [0; 3] })
        });
        let img = image::DynamicImage::ImageRgb8(img);
        let centre = rendered_centre(&img, 0.5).to_rgb8();
        assert_eq!(centre.dimensions(), (10, 10));
        assert!(centre.pixels().all(|p| p.0 == [255; 3]));
        assert_eq!(rendered_centre(&img, 1.0).to_rgb8().dimensions(), (20, 20));
    }
}
