//! Inline SVG charts: accuracy against time (the paper's Fig. 5) with the
//! share of frames answered `no_grasp`.

use std::fmt::Write;

/// One line of the chart: a name, a CSS class (colour and dash) and a
/// value in [0, 1] per bin (None: no frame in the bin).
pub struct Line<'a> {
    pub name: &'a str,
    pub class: &'a str,
    pub values: Vec<Option<f64>>,
}

const W: f64 = 640.0;
const H: f64 = 250.0;
const LEFT: f64 = 46.0;
const RIGHT: f64 = 150.0;
const TOP: f64 = 12.0;
const BOTTOM: f64 = 36.0;

/// A line chart of `lines` against time (bins of `bin_s` seconds, each
/// point at its bin's start), y from 0 to 100 %.
pub fn time_chart(lines: &[Line], bin_s: f64) -> String {
    let bins = lines.iter().map(|l| l.values.len()).max().unwrap_or(0);
    let t_max = (bins.max(1) as f64 * bin_s).max(bin_s);
    let pw = W - LEFT - RIGHT;
    let ph = H - TOP - BOTTOM;
    let x = |t: f64| LEFT + t / t_max * pw;
    let y = |v: f64| TOP + (1.0 - v) * ph;
    let mut s = format!(
        "<svg class=\"chart\" viewBox=\"0 0 {W} {H}\" width=\"{W}\" height=\"{H}\" \
         role=\"img\" aria-label=\"accuracy against time\">\n"
    );
    for k in 0..=4 {
        let v = f64::from(k) / 4.0;
        let _ = writeln!(
            s,
            "<line class=\"grid\" x1=\"{LEFT}\" x2=\"{:.1}\" y1=\"{:.1}\" y2=\"{:.1}\"/>\
             <text class=\"tick\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
            LEFT + pw,
            y(v),
            y(v),
            LEFT - 5.0,
            y(v) + 4.0,
            k * 25
        );
    }
    let step = nice_step(t_max);
    let mut t = 0.0;
    while t <= t_max + 1e-9 {
        let _ = writeln!(
            s,
            "<line class=\"axis\" x1=\"{0:.1}\" x2=\"{0:.1}\" y1=\"{1:.1}\" y2=\"{2:.1}\"/>\
             <text class=\"tick\" x=\"{0:.1}\" y=\"{3:.1}\" text-anchor=\"middle\">{4}</text>",
            x(t),
            TOP + ph,
            TOP + ph + 4.0,
            TOP + ph + 16.0,
            trim_float(t)
        );
        t += step;
    }
    let _ = writeln!(
        s,
        "<text class=\"label\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">time since the first frame (s)</text>\
         <text class=\"label\" transform=\"translate(12 {:.1}) rotate(-90)\" text-anchor=\"middle\">%</text>",
        LEFT + pw / 2.0,
        H - 4.0,
        TOP + ph / 2.0
    );
    for (k, line) in lines.iter().enumerate() {
        // The bins with a value, joined across empty bins (a video's frames
        // are farther apart than a bin when it is recorded at a low rate).
        let points: Vec<String> = line
            .values
            .iter()
            .enumerate()
            .filter_map(|(i, v)| Some(format!("{:.1},{:.1}", x(i as f64 * bin_s), y((*v)?))))
            .collect();
        if let [p] = points.as_slice() {
            let (px, py) = p.split_once(',').unwrap_or(("0", "0"));
            let _ = writeln!(
                s,
                "<circle class=\"{}\" cx=\"{px}\" cy=\"{py}\" r=\"2\"/>",
                line.class
            );
        } else if points.len() > 1 {
            let _ = writeln!(
                s,
                "<polyline class=\"{}\" points=\"{}\"/>",
                line.class,
                points.join(" ")
            );
        }
        let ly = TOP + 10.0 + k as f64 * 18.0;
        let lx = LEFT + pw + 12.0;
        let _ = writeln!(
            s,
            "<line class=\"{}\" x1=\"{lx:.1}\" x2=\"{:.1}\" y1=\"{ly:.1}\" y2=\"{ly:.1}\"/>\
             <text class=\"legend\" x=\"{:.1}\" y=\"{:.1}\">{}</text>",
            line.class,
            lx + 24.0,
            lx + 30.0,
            ly + 4.0,
            super::esc(line.name)
        );
    }
    s.push_str("</svg>\n");
    s
}

/// A tick step giving 4 to 10 ticks over `span`.
fn nice_step(span: f64) -> f64 {
    for step in [0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0] {
        if span / step <= 10.0 {
            return step;
        }
    }
    100.0
}

fn trim_float(t: f64) -> String {
    let s = format!("{t:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_bins_are_bridged_and_a_lone_point_is_a_dot() {
        let line = |class, values| Line {
            name: "multi <grasp>",
            class,
            values,
        };
        let svg = time_chart(
            &[
                line("multi", vec![Some(1.0), Some(0.5), None, Some(0.0)]),
                line("single", vec![None, Some(0.5)]),
            ],
            0.5,
        );
        assert_eq!(svg.matches("<polyline class=\"multi\"").count(), 1);
        assert_eq!(svg.matches("<circle class=\"single\"").count(), 1);
        assert!(svg.contains("multi &lt;grasp&gt;"));
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    }
}
