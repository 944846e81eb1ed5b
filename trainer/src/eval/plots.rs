//! PNG plots with plotters' bitmap backend, from plain data (curves,
//! matrices, series): the report and the summary build the data, this
//! module only draws. Text uses the toolkit's bundled font (`grasp_font`),
//! so every machine labels its plots, with no system font. Each function
//! returns the PNG's bytes, for the caller to write atomically.

use crate::error::PlotError;
use plotters::prelude::*;

/// Registers the bundled font with plotters once.
fn register_font() {
    static REGISTERED: std::sync::Once = std::sync::Once::new();
    REGISTERED.call_once(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, grasp_font::bytes())
            .unwrap_or_else(|_| panic!("the bundled font parses"));
    });
}

fn err<E: std::fmt::Debug>(e: E) -> PlotError {
    PlotError::Draw(format!("{e:?}"))
}

type Result<T, E = PlotError> = std::result::Result<T, E>;

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// Draws into a `width` x `height` white canvas and encodes it as PNG.
fn render_png(width: u32, height: u32, draw: impl FnOnce(&Area) -> Result<()>) -> Result<Vec<u8>> {
    register_font();
    let mut buf = vec![0u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        draw(&root)?;
        root.present().map_err(err)?;
    }
    let img = image::RgbImage::from_raw(width, height, buf).ok_or(PlotError::Buffer)?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

/// Accuracy against time, as the paper's Fig. 5: per-bin accuracy (0 to 1,
/// `None` for an empty bin) of single-grasp and multi-grasp objects, and
/// the share of their pre-shape frames answered `no_grasp` (empty: not
/// drawn).
pub struct TimeAccuracy<'a> {
    pub title: String,
    pub bin_s: f64,
    pub single: &'a [Option<f64>],
    pub multi: &'a [Option<f64>],
    pub single_no_grasp: &'a [Option<f64>],
    pub multi_no_grasp: &'a [Option<f64>],
}

/// The time-accuracy plot: single-grasp objects dashed, multi-grasp solid.
pub fn time_accuracy(plot: &TimeAccuracy) -> Result<Vec<u8>> {
    let series = |accuracy: &[Option<f64>]| -> Vec<(f64, f64)> {
        accuracy
            .iter()
            .enumerate()
            .filter_map(|(i, a)| a.map(|a| ((i as f64 + 0.5) * plot.bin_s, a * 100.0)))
            .collect()
    };
    let single = series(plot.single);
    let multi = series(plot.multi);
    let t_max = single
        .iter()
        .chain(&multi)
        .map(|p| p.0)
        .fold(plot.bin_s, f64::max)
        + plot.bin_s / 2.0;
    render_png(800, 500, |root| {
        let mut chart = ChartBuilder::on(root)
            .margin(20)
            .caption(&plot.title, ("sans-serif", 22))
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0f64..t_max, 0f64..100f64)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("time since onset (s)")
            .y_desc("pre-shape frames (%)")
            .draw()
            .map_err(err)?;
        let blue = RGBColor(31, 119, 180);
        let pink = RGBColor(214, 39, 140);
        chart
            .draw_series(DashedLineSeries::new(single, 8, 5, blue.stroke_width(2)))
            .map_err(err)?
            .label("single-grasp objects (dashed)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], blue));
        chart
            .draw_series(LineSeries::new(multi, pink.stroke_width(2)))
            .map_err(err)?
            .label("multi-grasp objects (solid)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], pink));
        // The abstentions, thin and pale: an answer of no_grasp is not a
        // wrong part.
        let pale_blue = RGBColor(140, 180, 215);
        let pale_pink = RGBColor(235, 150, 200);
        for (values, colour, label) in [
            (
                plot.single_no_grasp,
                pale_blue,
                "single-grasp: answered no_grasp",
            ),
            (
                plot.multi_no_grasp,
                pale_pink,
                "multi-grasp: answered no_grasp",
            ),
        ] {
            if values.is_empty() {
                continue;
            }
            chart
                .draw_series(DashedLineSeries::new(
                    series(values),
                    3,
                    4,
                    colour.stroke_width(1),
                ))
                .map_err(err)?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
        Ok(())
    })
}

/// Side of a confusion cell, and the margin for the class names.
const CELL: i32 = 90;
const LABEL_MARGIN: i32 = 100;

/// Row-normalised confusion matrix as a heat map (darker: more frames),
/// with counts in the cells and `names` along both axes.
pub fn confusion(matrix: &[Vec<u64>], names: &[&str]) -> Result<Vec<u8>> {
    let n = matrix.len();
    let size = (LABEL_MARGIN + CELL * n as i32 + 10) as u32;
    render_png(size, size, |root| {
        for (i, row) in matrix.iter().enumerate() {
            let total = row.iter().sum::<u64>().max(1) as f64;
            for (j, count) in row.iter().enumerate() {
                let fraction = *count as f64 / total;
                let shade = (255.0 * (1.0 - fraction)) as u8;
                let (x, y) = (
                    LABEL_MARGIN + j as i32 * CELL,
                    LABEL_MARGIN + i as i32 * CELL,
                );
                let corners = [(x, y), (x + CELL, y + CELL)];
                root.draw(&Rectangle::new(
                    corners,
                    RGBColor(shade, shade, 255).filled(),
                ))
                .map_err(err)?;
                root.draw(&Rectangle::new(corners, BLACK)).map_err(err)?;
                let colour = if fraction > 0.5 { WHITE } else { BLACK };
                root.draw(&Text::new(
                    format!("{count}"),
                    (x + 10, y + CELL / 2 - 8),
                    ("sans-serif", 18).into_font().color(&colour),
                ))
                .map_err(err)?;
            }
            let label = names.get(i).copied().unwrap_or("?");
            let along = LABEL_MARGIN + i as i32 * CELL;
            root.draw(&Text::new(
                label,
                (5, along + CELL / 2 - 8),
                ("sans-serif", 16),
            ))
            .map_err(err)?;
            root.draw(&Text::new(
                label,
                (along + 5, LABEL_MARGIN - 25),
                ("sans-serif", 16),
            ))
            .map_err(err)?;
        }
        Ok(())
    })
}

/// A line's name (empty: no legend entry) and its points: (x, error %,
/// std %), sorted by x.
pub type Series = (String, Vec<(f64, f64, f64)>);

/// Per-video error against x, one line per series, error bars of ± one
/// std, on a logarithmic x axis with `log_x`.
pub struct ErrorAgainstX {
    pub title: String,
    pub x_label: String,
    pub log_x: bool,
    pub series: Vec<Series>,
}

const SERIES_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 140),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

pub fn error_against_x(plot: &ErrorAgainstX) -> Result<Vec<u8>> {
    let xs = || plot.series.iter().flat_map(|(_, v)| v.iter().map(|p| p.0));
    let (lo, hi) = (
        xs().fold(f64::INFINITY, f64::min),
        xs().fold(f64::NEG_INFINITY, f64::max),
    );
    let highest = plot
        .series
        .iter()
        .flat_map(|(_, v)| v.iter().map(|p| p.1 + p.2))
        .fold(5.0, f64::max);
    let y = 0f64..(highest * 1.15).min(100.0);
    render_png(800, 500, |root| {
        let mut builder = ChartBuilder::on(root);
        builder
            .margin(20)
            .caption(&plot.title, ("sans-serif", 22))
            .x_label_area_size(40)
            .y_label_area_size(50);
        if plot.log_x {
            let x = (lo / 1.5)..(hi * 1.5);
            let chart = builder.build_cartesian_2d(x.log_scale(), y).map_err(err)?;
            draw_error_series(chart, plot)
        } else {
            let pad = if hi > lo { (hi - lo) * 0.06 } else { 0.5 };
            let chart = builder
                .build_cartesian_2d((lo - pad)..(hi + pad), y)
                .map_err(err)?;
            draw_error_series(chart, plot)
        }
    })
}

fn draw_error_series<'a, X>(
    mut chart: ChartContext<
        'a,
        BitMapBackend<'a>,
        Cartesian2d<X, plotters::coord::types::RangedCoordf64>,
    >,
    plot: &ErrorAgainstX,
) -> Result<()>
where
    X: Ranged<ValueType = f64> + plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let x_desc = if plot.log_x {
        format!("{} (log scale)", plot.x_label)
    } else {
        plot.x_label.clone()
    };
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("per-video error (%)")
        .draw()
        .map_err(err)?;
    for (i, (group, points)) in plot.series.iter().enumerate() {
        let colour = SERIES_COLOURS[i % SERIES_COLOURS.len()];
        let line = chart
            .draw_series(LineSeries::new(
                points.iter().map(|p| (p.0, p.1)),
                colour.stroke_width(2),
            ))
            .map_err(err)?;
        if !group.is_empty() {
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
    if plot.series.iter().any(|(g, _)| !g.is_empty()) {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(png: &[u8]) -> image::RgbImage {
        image::load_from_memory(png).unwrap().to_rgb8()
    }

    /// Pixels that are neither white nor the plot's colours: the black and
    /// grey of text, axes and grid.
    fn dark_pixels(img: &image::RgbImage, rows: std::ops::Range<u32>) -> usize {
        rows.flat_map(|y| (0..img.width()).map(move |x| (x, y)))
            .filter(|(x, y)| img.get_pixel(*x, *y).0.iter().all(|c| *c < 128))
            .count()
    }

    #[test]
    fn plots_are_labelled_with_the_bundled_font_and_no_system_font() {
        // The caption band (above the chart, which starts at 20 + ~30 px)
        // holds the title's text; without a title the chart moves up into
        // it, but its few tick-label pixels are far fewer than a title's.
        let curve = [Some(0.5), Some(0.75), None, Some(1.0)];
        let plot = |title: &str| TimeAccuracy {
            title: title.to_string(),
            bin_s: 0.1,
            single: &curve,
            multi: &curve,
            single_no_grasp: &curve,
            multi_no_grasp: &[],
        };
        let titled = decode(&time_accuracy(&plot("Accuracy against time (fc)")).unwrap());
        let untitled = decode(&time_accuracy(&plot("")).unwrap());
        let band = 0..45;
        let (with, without) = (
            dark_pixels(&titled, band.clone()),
            dark_pixels(&untitled, band),
        );
        assert!(with > without + 100, "no title text: {with} vs {without}");
    }

    #[test]
    fn confusion_cells_carry_their_counts_and_names() {
        let matrix = vec![vec![3, 1], vec![0, 4]];
        let named = decode(&confusion(&matrix, &["power", "pinch"]).unwrap());
        let unnamed = decode(&confusion(&matrix, &["", ""]).unwrap());
        assert_eq!(named.dimensions(), (100 + 180 + 10, 100 + 180 + 10));
        // the name margin above the cells: text only when names are given
        assert!(dark_pixels(&named, 70..95) > 50);
        assert_eq!(dark_pixels(&unnamed, 70..95), 0);
    }

    #[test]
    fn error_against_x_draws_on_linear_and_log_axes() {
        for log_x in [false, true] {
            let plot = ErrorAgainstX {
                title: "Per-video error against samples".into(),
                x_label: "samples".into(),
                log_x,
                series: vec![
                    ("fc".into(), vec![(1.0, 30.0, 5.0), (4.0, 20.0, 2.0)]),
                    ("lstm".into(), vec![(1.0, 25.0, 3.0), (4.0, 15.0, 1.0)]),
                ],
            };
            let img = decode(&error_against_x(&plot).unwrap());
            assert_eq!(img.dimensions(), (800, 500));
            assert!(dark_pixels(&img, 0..45) > 100, "log_x {log_x}: no title");
        }
    }
}
