//! A small software rasteriser for `grasp-gen objects show`: an object's
//! mesh from the top, the front and the side (orthographic, one scale for
//! all three views), flat shaded with a z-buffer, and its grasp boxes as
//! wireframes coloured by pre-shape and numbered, with a legend.

use crate::catalog::{ObjectSpec, TriMesh};
use grasp_schema::Preshape;
use image::{Rgb, RgbImage};

const PANEL: u32 = 360;
const TITLE: u32 = 28;
const LINE: u32 = 20;
const BG: Rgb<u8> = Rgb([246, 246, 242]);
const INK: Rgb<u8> = Rgb([30, 30, 30]);

/// The colour of a pre-shape's boxes.
pub fn preshape_colour(p: Preshape) -> Rgb<u8> {
    match p {
        Preshape::Power => Rgb([214, 40, 40]),
        Preshape::Lateral => Rgb([30, 90, 220]),
        Preshape::Pinch => Rgb([20, 150, 60]),
        Preshape::Pinch3 => Rgb([235, 130, 0]),
    }
}

/// A view: image right and image up as object-frame directions, and the
/// direction towards the viewer (for depth and shading).
struct View {
    name: &'static str,
    right: [f64; 3],
    up: [f64; 3],
    toward: [f64; 3],
}

const VIEWS: [View; 3] = [
    View {
        name: "top (x right, y up)",
        right: [1.0, 0.0, 0.0],
        up: [0.0, 1.0, 0.0],
        toward: [0.0, 0.0, 1.0],
    },
    View {
        name: "front (x right, z up)",
        right: [1.0, 0.0, 0.0],
        up: [0.0, 0.0, 1.0],
        toward: [0.0, -1.0, 0.0],
    },
    View {
        name: "side (y right, z up)",
        right: [0.0, 1.0, 0.0],
        up: [0.0, 0.0, 1.0],
        toward: [1.0, 0.0, 0.0],
    },
];

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Renders the object and its boxes into an image.
pub fn render_object(object: &ObjectSpec, mesh: &TriMesh) -> RgbImage {
    let legend_h = LINE * (object.parts.len() as u32 + 1) + 8;
    let mut img = RgbImage::from_pixel(3 * PANEL, TITLE + PANEL + legend_h, BG);
    let (lo, hi) = mesh.bounds();
    let centre = [0, 1, 2].map(|k| (lo[k] + hi[k]) / 2.0);
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max).max(1e-6);
    let scale = (PANEL as f64 - 40.0) / extent;
    let title = format!(
        "{} ({})  {:.0} x {:.0} x {:.0} mm",
        object.id,
        object.name,
        (hi[0] - lo[0]) * 1e3,
        (hi[1] - lo[1]) * 1e3,
        (hi[2] - lo[2]) * 1e3
    );
    text(&mut img, 8, 8, &title, INK, 2);
    for (i, view) in VIEWS.iter().enumerate() {
        let ox = i as u32 * PANEL;
        let project = |p: [f64; 3]| -> (f64, f64, f64) {
            let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
            (
                ox as f64 + PANEL as f64 / 2.0 + dot(d, view.right) * scale,
                TITLE as f64 + PANEL as f64 / 2.0 - dot(d, view.up) * scale,
                dot(d, view.toward),
            )
        };
        shade(&mut img, mesh, &project, view, ox);
        for (n, part) in object.parts.iter().enumerate() {
            let colour = preshape_colour(part.grasp_type.preshape());
            let c = part.corners().map(&project);
            for (a, b) in BOX_EDGES {
                line(&mut img, (c[a].0, c[a].1), (c[b].0, c[b].1), colour, ox);
            }
            // Approach arrow: from outside the box to its centre along +Z.
            let r = part.rotation_matrix();
            let z = [r[(0, 2)], r[(1, 2)], r[(2, 2)]];
            let back = 0.6 * part.size[2] + 0.012;
            let tail = [0, 1, 2].map(|k| part.center[k] - z[k] * back);
            let (p0, p1) = (project(tail), project(part.center));
            line(&mut img, (p0.0, p0.1), (p1.0, p1.1), colour, ox);
            let label = format!("{}", n + 1);
            text(
                &mut img,
                p0.0 as i64 - 4,
                p0.1 as i64 - 8,
                &label,
                colour,
                2,
            );
        }
        text(
            &mut img,
            ox as i64 + 8,
            (TITLE + PANEL - 18) as i64,
            view.name,
            INK,
            1,
        );
        for y in TITLE..TITLE + PANEL {
            img.put_pixel(ox, y, INK);
        }
    }
    let mut y = TITLE + PANEL + 6;
    for (n, part) in object.parts.iter().enumerate() {
        let p = part.grasp_type.preshape();
        let mut tags = Vec::new();
        match part.upside_down {
            crate::catalog::UpsideDown::Never => {}
            crate::catalog::UpsideDown::May => tags.push("may be upside down"),
            crate::catalog::UpsideDown::Must => tags.push("upside down"),
        }
        if part.pronation == crate::catalog::Pronation::None {
            tags.push("no pronation");
        }
        if part.table_border {
            tags.push("table border");
        }
        let line_text = format!(
            "{} {}: {} ({}){}{}",
            n + 1,
            part.name,
            part.grasp_type.name(),
            p.name(),
            if tags.is_empty() { "" } else { "  " },
            tags.join(", ")
        );
        text(&mut img, 10, y as i64, &line_text, preshape_colour(p), 2);
        y += LINE;
    }
    text(
        &mut img,
        10,
        y as i64,
        "arrows: approach (box +Z). red power, blue lateral, green pinch, orange pinch3",
        INK,
        1,
    );
    img
}

const BOX_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

fn shade(
    img: &mut RgbImage,
    mesh: &TriMesh,
    project: &dyn Fn([f64; 3]) -> (f64, f64, f64),
    view: &View,
    ox: u32,
) {
    let mut depth = vec![f64::NEG_INFINITY; (PANEL * PANEL) as usize];
    // Light from the viewer, a little from the upper left.
    let light = {
        let l = [0, 1, 2].map(|k| view.toward[k] + 0.4 * view.up[k] - 0.3 * view.right[k]);
        let n = dot(l, l).sqrt();
        l.map(|x| x / n)
    };
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
        let n = crate::catalog::shapes::cross(
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        let len = dot(n, n).sqrt();
        if len == 0.0 {
            continue;
        }
        let lum = 0.25 + 0.75 * (dot(n, light) / len).abs();
        let base = [178.0, 170.0, 160.0];
        let colour = Rgb(base.map(|c: f64| (c * lum).min(255.0) as u8));
        let (p, q, r) = (project(a), project(b), project(c));
        fill_triangle(img, &mut depth, [p, q, r], colour, ox);
    }
}

fn fill_triangle(
    img: &mut RgbImage,
    depth: &mut [f64],
    t: [(f64, f64, f64); 3],
    colour: Rgb<u8>,
    ox: u32,
) {
    let min_x = t
        .iter()
        .map(|p| p.0)
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(ox as f64) as i64;
    let max_x = t
        .iter()
        .map(|p| p.0)
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .min((ox + PANEL - 1) as f64) as i64;
    let min_y = t
        .iter()
        .map(|p| p.1)
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(TITLE as f64) as i64;
    let max_y = t
        .iter()
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .min((TITLE + PANEL - 1) as f64) as i64;
    let area = (t[1].0 - t[0].0) * (t[2].1 - t[0].1) - (t[2].0 - t[0].0) * (t[1].1 - t[0].1);
    if area.abs() < 1e-12 {
        return;
    }
    for y in min_y..=max_y {
        for x in min_x..=max_x {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let w0 = ((t[1].0 - px) * (t[2].1 - py) - (t[2].0 - px) * (t[1].1 - py)) / area;
            let w1 = ((t[2].0 - px) * (t[0].1 - py) - (t[0].0 - px) * (t[2].1 - py)) / area;
            let w2 = 1.0 - w0 - w1;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            let z = w0 * t[0].2 + w1 * t[1].2 + w2 * t[2].2;
            let di = ((y as u32 - TITLE) * PANEL + (x as u32 - ox)) as usize;
            if z > depth[di] {
                depth[di] = z;
                img.put_pixel(x as u32, y as u32, colour);
            }
        }
    }
}

/// A 2-pixel line, clipped to the panel starting at `ox`.
fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), colour: Rgb<u8>, ox: u32) {
    let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
    for s in 0..=steps {
        let t = s as f64 / steps as f64;
        let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (xi, yi) = (x as i64 + dx, y as i64 + dy);
            if xi >= ox as i64
                && xi < (ox + PANEL) as i64
                && yi >= TITLE as i64
                && yi < (TITLE + PANEL) as i64
            {
                img.put_pixel(xi as u32, yi as u32, colour);
            }
        }
    }
}

/// Draws text with the toolkit's bundled font (`grasp_font`), the top-left
/// corner of its line box at (`x`, `y`): `scale` 1 is small print (12 px),
/// 2 is body text (18 px).
pub fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, colour: Rgb<u8>, scale: i64) {
    grasp_font::draw_text(img, x, y, s, colour, 6.0 + 6.0 * scale as f32);
}
