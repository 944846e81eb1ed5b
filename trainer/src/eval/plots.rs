//! PNG plots with plotters' bitmap backend. Text needs a TrueType font: the
//! first one found among `GRASP_PLOT_FONT` and common system locations is
//! registered (pure-Rust `ab_glyph`, no fontconfig). Without one the plots
//! are drawn without text (the Markdown report carries the numbers and the
//! legend), rather than failing on a fresh machine.

use super::report::Report;
use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

const FONT_CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Registers a font once; whether text can be drawn.
pub fn font_available() -> bool {
    static FOUND: OnceLock<bool> = OnceLock::new();
    *FOUND.get_or_init(|| {
        let env = std::env::var("GRASP_PLOT_FONT").ok();
        env.iter()
            .map(String::as_str)
            .chain(FONT_CANDIDATES.iter().copied())
            .filter_map(|p| std::fs::read(p).ok())
            .any(|bytes| {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
            })
    })
}

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plot: {e:?}")
}

/// Accuracy against time for single-grasp (dashed) and multi-grasp (solid)
/// objects, as the paper's Fig. 5.
pub fn time_accuracy(r: &Report, path: &Path) -> Result<()> {
    let text = font_available();
    let root = BitMapBackend::new(path, (800, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let series = |c: &super::metrics::Curve| -> Vec<(f64, f64)> {
        c.accuracy()
            .iter()
            .enumerate()
            .filter_map(|(i, a)| a.map(|a| ((i as f64 + 0.5) * r.time_bin_s, a * 100.0)))
            .collect()
    };
    let single = series(&r.time_single);
    let multi = series(&r.time_multi);
    let t_max = single
        .iter()
        .chain(&multi)
        .map(|p| p.0)
        .fold(r.time_bin_s, f64::max)
        + r.time_bin_s / 2.0;
    let mut builder = ChartBuilder::on(&root);
    builder.margin(20);
    if text {
        builder
            .caption(
                format!("Accuracy against time ({}, {})", r.mode, r.head),
                ("sans-serif", 22),
            )
            .x_label_area_size(40)
            .y_label_area_size(50);
    }
    let mut chart = builder
        .build_cartesian_2d(0f64..t_max, 0f64..100f64)
        .map_err(err)?;
    if text {
        chart
            .configure_mesh()
            .x_desc("time since onset (s)")
            .y_desc("accuracy (%)")
            .draw()
            .map_err(err)?;
    } else {
        for y in [0.0, 25.0, 50.0, 75.0, 100.0] {
            chart
                .draw_series(LineSeries::new(
                    vec![(0.0, y), (t_max, y)],
                    &RGBColor(220, 220, 220),
                ))
                .map_err(err)?;
        }
    }
    let blue = RGBColor(31, 119, 180);
    let pink = RGBColor(214, 39, 140);
    let s = chart
        .draw_series(DashedLineSeries::new(single, 8, 5, blue.stroke_width(2)))
        .map_err(err)?;
    if text {
        s.label("single-grasp objects (dashed)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], blue));
    }
    let m = chart
        .draw_series(LineSeries::new(multi, pink.stroke_width(2)))
        .map_err(err)?;
    if text {
        m.label("multi-grasp objects (solid)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], pink));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// Row-normalised confusion matrix as a heat map (darker: more frames).
pub fn confusion(m: &[Vec<u64>], path: &Path) -> Result<()> {
    let text = font_available();
    let n = m.len();
    let cell = 90i32;
    let pad = if text { 100 } else { 10 };
    let size = (pad + cell * n as i32 + 10) as u32;
    let root = BitMapBackend::new(path, (size, size)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let names = grasp_schema::taxonomy::Class::names();
    for (i, row) in m.iter().enumerate() {
        let total = row.iter().sum::<u64>().max(1) as f64;
        for (j, v) in row.iter().enumerate() {
            let f = *v as f64 / total;
            let shade = (255.0 * (1.0 - f)) as u8;
            let (x, y) = (pad + j as i32 * cell, pad + i as i32 * cell);
            root.draw(&Rectangle::new(
                [(x, y), (x + cell, y + cell)],
                RGBColor(shade, shade, 255).filled(),
            ))
            .map_err(err)?;
            root.draw(&Rectangle::new([(x, y), (x + cell, y + cell)], BLACK))
                .map_err(err)?;
            if text {
                let colour = if f > 0.5 { WHITE } else { BLACK };
                root.draw(&Text::new(
                    format!("{v}"),
                    (x + 10, y + cell / 2 - 8),
                    ("sans-serif", 18).into_font().color(&colour),
                ))
                .map_err(err)?;
            }
        }
        if text {
            let label = names.get(i).copied().unwrap_or("?");
            root.draw(&Text::new(
                label,
                (5, pad + i as i32 * cell + cell / 2 - 8),
                ("sans-serif", 16),
            ))
            .map_err(err)?;
            root.draw(&Text::new(
                label,
                (pad + i as i32 * cell + 5, pad - 25),
                ("sans-serif", 16),
            ))
            .map_err(err)?;
        }
    }
    root.present().map_err(err)?;
    Ok(())
}

const SERIES_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 140),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Per-video error (%) against x for the summary's entries with an x, one
/// line per label group (`GROUP/NAME`), error bars of ± one std over seeds,
/// on a logarithmic x axis with `log_x`. Returns the PNG's bytes, so the
/// caller can write them atomically.
pub fn error_against_x(s: &super::summary::Summary) -> Result<Vec<u8>> {
    let (w, h) = (800u32, 500u32);
    let log = s.spec.log_x;
    let series = error_series(s)?;
    let xs = || series.iter().flat_map(|(_, v)| v.iter().map(|p| p.0));
    let (lo, hi) = (
        xs().fold(f64::INFINITY, f64::min),
        xs().fold(f64::NEG_INFINITY, f64::max),
    );
    let highest = series
        .iter()
        .flat_map(|(_, v)| v.iter().map(|p| p.1 + p.2))
        .fold(5.0, f64::max);
    let y = 0f64..(highest * 1.15).min(100.0);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let mut builder = error_chart_builder(&root, s);
        if log {
            let x = (lo / 1.5)..(hi * 1.5);
            let chart = builder.build_cartesian_2d(x.log_scale(), y).map_err(err)?;
            draw_error_series(chart, s, &series)?;
        } else {
            let pad = if hi > lo { (hi - lo) * 0.06 } else { 0.5 };
            let chart = builder
                .build_cartesian_2d((lo - pad)..(hi + pad), y)
                .map_err(err)?;
            draw_error_series(chart, s, &series)?;
        }
        root.present().map_err(err)?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).context("plot buffer size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

/// A line's name and its points: (x, error %, std %), sorted by x.
type Series = (String, Vec<(f64, f64, f64)>);

fn error_series(s: &super::summary::Summary) -> Result<Vec<Series>> {
    let mut series: Vec<Series> = Vec::new();
    for r in &s.rows {
        let Some(x) = r.x else { continue };
        if s.spec.log_x && x <= 0.0 {
            anyhow::bail!("report `{}`: x = {x} cannot go on a log axis", r.label);
        }
        let group = r.group_name().0.to_string();
        let point = (x, r.video_error.mean * 100.0, r.video_error.std * 100.0);
        match series.iter_mut().find(|(g, _)| *g == group) {
            Some((_, v)) => v.push(point),
            None => series.push((group, vec![point])),
        }
    }
    for (_, v) in &mut series {
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    Ok(series)
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn error_chart_builder<'a, 'b>(
    root: &'a Area<'b>,
    s: &super::summary::Summary,
) -> ChartBuilder<'a, 'b, BitMapBackend<'b>> {
    let mut builder = ChartBuilder::on(root);
    builder.margin(20);
    if font_available() {
        let title = s
            .spec
            .title
            .clone()
            .unwrap_or_else(|| format!("Per-video error against {}", s.x_label()));
        builder
            .caption(title, ("sans-serif", 22))
            .x_label_area_size(40)
            .y_label_area_size(50);
    }
    builder
}

fn draw_error_series<'a, X>(
    mut chart: ChartContext<
        'a,
        BitMapBackend<'a>,
        Cartesian2d<X, plotters::coord::types::RangedCoordf64>,
    >,
    s: &super::summary::Summary,
    series: &[Series],
) -> Result<()>
where
    X: Ranged<ValueType = f64> + plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let text = font_available();
    if text {
        let x_desc = if s.spec.log_x {
            format!("{} (log scale)", s.x_label())
        } else {
            s.x_label().to_string()
        };
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc("per-video error (%)")
            .draw()
            .map_err(err)?;
    }
    for (i, (group, points)) in series.iter().enumerate() {
        let colour = SERIES_COLOURS[i % SERIES_COLOURS.len()];
        let line = chart
            .draw_series(LineSeries::new(
                points.iter().map(|p| (p.0, p.1)),
                colour.stroke_width(2),
            ))
            .map_err(err)?;
        if text && !group.is_empty() {
            line.label(group.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        }
        chart
            .draw_series(points.iter().map(|p| {
                ErrorBar::new_vertical(
                    p.0,
                    (p.1 - p.2).max(0.0),
                    p.1,
                    (p.1 + p.2).min(100.0),
                    colour.stroke_width(2),
                    10,
                )
            }))
            .map_err(err)?;
        chart
            .draw_series(
                points
                    .iter()
                    .map(|p| Circle::new((p.0, p.1), 4, colour.filled())),
            )
            .map_err(err)?;
    }
    if text && series.iter().any(|(g, _)| !g.is_empty()) {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}
