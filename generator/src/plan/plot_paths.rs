//! The `grasp-gen plan --show` picture: one cell per (object, part,
//! condition) with a top view (x right, y up) and a side view (x right,
//! z up) of the planned camera paths over the table and the object's
//! silhouette, coloured by pre-shape.

use super::error::{PlanError, Result};
use super::wrist;
use super::Planner;
use grasp_schema::{Preshape, SequencePlan};
use image::{Rgb, RgbImage};
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::Path;

const CELL: u32 = 230; // panel size, pixels
const GAP: u32 = 8;
const TITLE: u32 = 14;
const COLUMNS: u32 = 3;
const HEADER: u32 = 40;

const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const INK: Rgb<u8> = Rgb([40, 40, 40]);
const FRAME: Rgb<u8> = Rgb([170, 170, 170]);
const TABLE: Rgb<u8> = Rgb([233, 220, 196]);
const TABLE_EDGE: Rgb<u8> = Rgb([190, 170, 135]);
const AREA: Rgb<u8> = Rgb([200, 200, 200]);
const OBJECT: Rgb<u8> = Rgb([150, 150, 150]);

/// World-to-pixel mapping of one panel: horizontal world axis `h`, vertical `v`.
#[derive(Clone, Copy)]
struct View {
    h: usize,
    v: usize,
    min: [f64; 2],
    scale: f64, // pixels per metre
    origin: (i64, i64),
}

impl View {
    fn fit(h: usize, v: usize, points: &[Vector3<f64>], origin: (i64, i64)) -> View {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            for (k, axis) in [h, v].into_iter().enumerate() {
                lo[k] = lo[k].min(p[axis]);
                hi[k] = hi[k].max(p[axis]);
            }
        }
        let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.05) * 1.08;
        let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        View {
            h,
            v,
            min: [centre[0] - span / 2.0, centre[1] - span / 2.0],
            scale: f64::from(CELL) / span,
            origin,
        }
    }

    fn px(&self, p: &Vector3<f64>) -> (i64, i64) {
        let x = (p[self.h] - self.min[0]) * self.scale;
        let y = (p[self.v] - self.min[1]) * self.scale;
        (
            self.origin.0 + x as i64,
            self.origin.1 + i64::from(CELL) - y as i64,
        )
    }
}

struct Canvas {
    img: RgbImage,
    clip: Option<(i64, i64, i64, i64)>,
}

impl Canvas {
    fn put(&mut self, x: i64, y: i64, c: Rgb<u8>) {
        if let Some((x0, y0, x1, y1)) = self.clip {
            if x < x0 || y < y0 || x >= x1 || y >= y1 {
                return;
            }
        }
        if x >= 0 && y >= 0 && (x as u32) < self.img.width() && (y as u32) < self.img.height() {
            self.img.put_pixel(x as u32, y as u32, c);
        }
    }

    fn rect(&mut self, a: (i64, i64), b: (i64, i64), c: Rgb<u8>) {
        for y in a.1.min(b.1)..=a.1.max(b.1) {
            for x in a.0.min(b.0)..=a.0.max(b.0) {
                self.put(x, y, c);
            }
        }
    }

    fn outline(&mut self, a: (i64, i64), b: (i64, i64), c: Rgb<u8>) {
        let (x0, x1, y0, y1) = (a.0.min(b.0), a.0.max(b.0), a.1.min(b.1), a.1.max(b.1));
        self.line((x0, y0), (x1, y0), c, 1);
        self.line((x1, y0), (x1, y1), c, 1);
        self.line((x1, y1), (x0, y1), c, 1);
        self.line((x0, y1), (x0, y0), c, 1);
    }

    fn line(&mut self, a: (i64, i64), b: (i64, i64), c: Rgb<u8>, width: i64) {
        let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).max(1);
        for s in 0..=steps {
            let x = a.0 + (b.0 - a.0) * s / steps;
            let y = a.1 + (b.1 - a.1) * s / steps;
            self.dot((x, y), width / 2, c);
        }
    }

    fn dot(&mut self, p: (i64, i64), r: i64, c: Rgb<u8>) {
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy <= r * r + r {
                    self.put(p.0 + dx, p.1 + dy, c);
                }
            }
        }
    }

    fn ring(&mut self, p: (i64, i64), r: i64, c: Rgb<u8>) {
        for k in 0..64 {
            let a = k as f64 / 64.0 * std::f64::consts::TAU;
            self.put(
                p.0 + (r as f64 * a.cos()).round() as i64,
                p.1 + (r as f64 * a.sin()).round() as i64,
                c,
            );
        }
    }

    fn text(&mut self, x: i64, y: i64, s: &str, c: Rgb<u8>) {
        crate::raster::text(&mut self.img, x, y, s, c, 1);
    }
}

/// Draws the plans (grouped by object, part and condition) into a PNG.
pub fn draw_paths(plans: &[&SequencePlan], planner: &Planner, out: &Path) -> Result<()> {
    let mut groups: BTreeMap<(String, String, String), Vec<&SequencePlan>> = BTreeMap::new();
    for p in plans {
        groups
            .entry((
                p.key.object.clone(),
                p.key.part.clone(),
                p.key.condition.to_string(),
            ))
            .or_default()
            .push(p);
    }
    if groups.is_empty() {
        return Err(PlanError::NothingToDraw);
    }
    let scene = &planner.config().plan.scene;
    // Common bounds for every cell: all paths and the placement area.
    let (alo, ahi) = scene.placement_bounds();
    let mut pts: Vec<Vector3<f64>> = plans
        .iter()
        .flat_map(|p| p.frames.iter().map(|f| Vector3::from(f.camera.position)))
        .collect();
    pts.push(Vector3::new(alo[0], alo[1], scene.table_height));
    pts.push(Vector3::new(ahi[0], ahi[1], scene.table_height + 0.1));
    pts.push(Vector3::new(
        scene.near_edge_x(),
        alo[1],
        scene.table_height - scene.table_thickness,
    ));

    let cell_w = 2 * CELL + 3 * GAP;
    let cell_h = CELL + TITLE + 2 * GAP;
    let rows = (groups.len() as u32).div_ceil(COLUMNS);
    let mut canvas = Canvas {
        img: RgbImage::from_pixel(COLUMNS * cell_w + GAP, HEADER + rows * cell_h + GAP, WHITE),
        clip: None,
    };
    draw_header(&mut canvas, plans.len());
    for (i, ((object, part, condition), group)) in groups.iter().enumerate() {
        let ox = i64::from(GAP + (i as u32 % COLUMNS) * cell_w);
        let oy = i64::from(HEADER + (i as u32 / COLUMNS) * cell_h);
        canvas.clip = None;
        canvas.text(ox, oy + 2, &format!("{object}/{part} ({condition})"), INK);
        let top = View::fit(0, 1, &pts, (ox, oy + i64::from(TITLE)));
        let side = View::fit(
            0,
            2,
            &pts,
            (ox + i64::from(CELL + GAP), oy + i64::from(TITLE)),
        );
        for view in [top, side] {
            draw_panel(&mut canvas, &view, planner, group);
        }
    }
    grasp_support::atomic::write_atomic_with(out, |tmp| -> Result<()> {
        canvas
            .img
            .save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| PlanError::Image {
                path: out.to_path_buf(),
                source: Box::new(e),
            })
    })
}

fn draw_header(c: &mut Canvas, count: usize) {
    c.text(
        i64::from(GAP),
        6,
        &format!("{count} planned camera paths. left: top view (x right, y up); right: side view (x right, z up). o = start, dot = target"),
        INK,
    );
    let mut x = i64::from(GAP);
    for p in Preshape::ALL {
        c.rect((x, 22), (x + 10, 30), crate::raster::preshape_colour(p));
        c.text(x + 14, 23, p.name(), INK);
        x += 14 + grasp_font::text_width(p.name(), 12.0).ceil() as i64 + 16;
    }
    c.text(x + 10, 23, "grey: table top and object silhouette", INK);
}

fn draw_panel(c: &mut Canvas, view: &View, planner: &Planner, plans: &[&SequencePlan]) {
    let (ox, oy) = view.origin;
    let size = i64::from(CELL);
    c.clip = Some((ox, oy, ox + size, oy + size));
    let scene = &planner.config().plan.scene;
    let (lo, hi) = scene.table_slab();
    let (alo, ahi) = scene.placement_bounds();
    let h = scene.table_height;
    if view.v == 1 {
        let a = view.px(&Vector3::new(lo[0], lo[1], h));
        let b = view.px(&Vector3::new(hi[0], hi[1], h));
        c.rect(a, b, TABLE);
        c.outline(a, b, TABLE_EDGE);
        let a = view.px(&Vector3::new(alo[0], alo[1], h));
        let b = view.px(&Vector3::new(ahi[0], ahi[1], h));
        c.outline(a, b, AREA);
    } else {
        let a = view.px(&Vector3::new(lo[0], 0.0, lo[2]));
        let b = view.px(&Vector3::new(hi[0], 0.0, hi[2]));
        c.rect(a, b, TABLE);
        c.outline(a, b, TABLE_EDGE);
    }
    for plan in plans {
        draw_object(c, view, planner, plan);
    }
    for plan in plans {
        draw_path(c, view, plan);
    }
    // Scale bar: 10 cm.
    let bar = (0.1 * view.scale) as i64;
    c.line(
        (ox + 4, oy + size - 6),
        (ox + 4 + bar, oy + size - 6),
        INK,
        1,
    );
    c.text(ox + 8 + bar, oy + size - 10, "10cm", INK);
    c.clip = None;
    c.outline((ox, oy), (ox + size - 1, oy + size - 1), FRAME);
}

fn draw_object(c: &mut Canvas, view: &View, planner: &Planner, plan: &SequencePlan) {
    let Some(geo) = planner.object(&plan.key.object) else {
        return;
    };
    let q = wrist::from_wxyz(plan.object.pose.rotation_wxyz);
    let t = Vector3::from(plan.object.pose.position);
    let scale = Vector3::from(plan.object.axis_scale());
    for tri in &geo.outline {
        let [a, b, d] = tri.map(|v| view.px(&(q * v.component_mul(&scale) + t)));
        c.triangle(a, b, d, OBJECT);
    }
}

fn draw_path(c: &mut Canvas, view: &View, plan: &SequencePlan) {
    let color = crate::raster::preshape_colour(plan.preshape);
    let pts: Vec<(i64, i64)> = plan
        .frames
        .iter()
        .map(|f| view.px(&Vector3::from(f.camera.position)))
        .collect();
    for w in pts.windows(2) {
        c.line(w[0], w[1], color, 2);
    }
    if let (Some(first), Some(last)) = (plan.frames.first(), plan.frames.last()) {
        c.ring(view.px(&Vector3::from(first.camera.position)), 3, color);
        // The final view direction, 5 cm long.
        let q = wrist::from_wxyz(last.camera.rotation_wxyz);
        let p = Vector3::from(last.camera.position);
        c.line(
            view.px(&p),
            view.px(&(p + wrist::view_direction(&q) * 0.05)),
            INK,
            1,
        );
    }
    c.dot(view.px(&Vector3::from(plan.target)), 2, INK);
}

impl Canvas {
    /// Fills a triangle (pixel centres inside, either winding).
    fn triangle(&mut self, a: (i64, i64), b: (i64, i64), d: (i64, i64), c: Rgb<u8>) {
        let edge = |p: (i64, i64), q: (i64, i64), x: i64, y: i64| {
            (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0)
        };
        let area = edge(a, b, d.0, d.1);
        if area == 0 {
            self.line(a, b, c, 1);
            self.line(b, d, c, 1);
            return;
        }
        let (x0, x1) = (a.0.min(b.0).min(d.0), a.0.max(b.0).max(d.0));
        let (y0, y1) = (a.1.min(b.1).min(d.1), a.1.max(b.1).max(d.1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (w0, w1, w2) = (edge(b, d, x, y), edge(d, a, x, y), edge(a, b, x, y));
                let inside = if area > 0 {
                    w0 >= 0 && w1 >= 0 && w2 >= 0
                } else {
                    w0 <= 0 && w1 <= 0 && w2 <= 0
                };
                if inside {
                    self.put(x, y, c);
                }
            }
        }
    }
}
