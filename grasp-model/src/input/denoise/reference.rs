//! The filter before the fast form (and the estimate as first written), kept
//! for the tests to compare the fast one with.

use super::*;

/// [`super::noise_sigma`] as it was first written, in f64 per pixel.
pub(super) fn noise_sigma(img: &RgbImage) -> f32 {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w < 3 || h < 3 {
        return 0.0;
    }
    const MASK: [[f64; 3]; 3] = [[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]];
    let raw = img.as_raw();
    let mut total = 0.0f64;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            for c in 0..3 {
                let mut r = 0.0;
                for (dy, row) in MASK.iter().enumerate() {
                    for (dx, m) in row.iter().enumerate() {
                        r += m * f64::from(raw[((y + dy - 1) * w + x + dx - 1) * 3 + c]);
                    }
                }
                total += r.abs();
            }
        }
    }
    let count = 3.0 * 6.0 * ((w - 2) * (h - 2)) as f64;
    let sigma = (std::f64::consts::FRAC_PI_2).sqrt() * total / count / 255.0;
    sigma as f32
}

/// [`super::nl_means`] as it was first written: every offset of the
/// window on its own, the patch sums from running row sums, `f32::exp`.
pub(super) fn nl_means(img: &RgbImage, sigma: f32, h: f32) -> RgbImage {
    let (w, hgt) = (img.width() as usize, img.height() as usize);
    if w == 0 || hgt == 0 || h <= 0.0 || !h.is_finite() || !sigma.is_finite() {
        return img.clone();
    }
    let pad = PATCH_RADIUS + SEARCH_RADIUS;
    let padded = Padded::new(img, pad);
    let (pw, ph) = (padded.width, padded.height);
    // The patch distances are needed wherever a pixel or a searched pixel
    // sits: the image plus the search radius on every side.
    let dw = w + 2 * SEARCH_RADIUS;
    let patch_area = ((2 * PATCH_RADIUS + 1) * (2 * PATCH_RADIUS + 1)) as f32;
    let two_sigma2 = 2.0 * sigma * sigma;
    let inv_h2 = 1.0 / (h * h);
    let mut acc = vec![0f32; w * hgt * 3];
    let mut weights = vec![0f32; w * hgt];
    let mut diff = vec![0f32; pw * ph];
    let mut rows = vec![0f32; dw * ph];
    let s = SEARCH_RADIUS as isize;
    for oy in -s..=s {
        for ox in -s..=s {
            // Squared colour difference between each pixel and its
            // neighbour at (ox, oy), where both are inside the padding.
            squared_differences(&padded, ox, oy, &mut diff);
            box_rows(&diff, pw, ph, dw, &mut rows);
            for y in 0..hgt {
                for x in 0..w {
                    // Patch distance of the pixel (x, y): the box sum
                    // centred on it, read from the column sums.
                    let d = box_column(&rows, dw, x + SEARCH_RADIUS, y + SEARCH_RADIUS)
                        / (3.0 * patch_area);
                    let x2 = (d - two_sigma2).max(0.0) * inv_h2;
                    if x2 > NEGLIGIBLE {
                        continue;
                    }
                    let weight = (-x2).exp();
                    let (sx, sy) = ((x + pad) as isize + ox, (y + pad) as isize + oy);
                    let q = padded.at(sx as usize, sy as usize);
                    let i = y * w + x;
                    weights[i] += weight;
                    for c in 0..3 {
                        acc[i * 3 + c] += weight * q[c];
                    }
                }
            }
        }
    }
    let mut out = RgbImage::new(w as u32, hgt as u32);
    for (i, px) in out.pixels_mut().enumerate() {
        for c in 0..3 {
            let v = acc[i * 3 + c] / weights[i];
            px.0[c] = (v * 255.0).round().clamp(0.0, 255.0) as u8;
        }
    }
    out
}

/// The image in [0, 1] floats with `pad` mirrored pixels on every side.
struct Padded {
    data: Vec<f32>,
    width: usize,
    height: usize,
}

impl Padded {
    fn new(img: &RgbImage, pad: usize) -> Padded {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let (width, height) = (w + 2 * pad, h + 2 * pad);
        let raw = img.as_raw();
        let mut data = vec![0f32; width * height * 3];
        for y in 0..height {
            let sy = mirror(y as isize - pad as isize, h);
            for x in 0..width {
                let sx = mirror(x as isize - pad as isize, w);
                for c in 0..3 {
                    data[(y * width + x) * 3 + c] = f32::from(raw[(sy * w + sx) * 3 + c]) / 255.0;
                }
            }
        }
        Padded {
            data,
            width,
            height,
        }
    }

    fn at(&self, x: usize, y: usize) -> [f32; 3] {
        let i = (y * self.width + x) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// `diff[p]` = the squared colour difference between the padded pixel p and
/// p + (ox, oy), over the pixels where both are inside the padding (0
/// elsewhere, never read).
fn squared_differences(p: &Padded, ox: isize, oy: isize, diff: &mut [f32]) {
    let (w, h) = (p.width as isize, p.height as isize);
    diff.fill(0.0);
    for y in 0..h {
        let qy = y + oy;
        if !(0..h).contains(&qy) {
            continue;
        }
        for x in 0..w {
            let qx = x + ox;
            if !(0..w).contains(&qx) {
                continue;
            }
            let a = ((y * w + x) * 3) as usize;
            let b = ((qy * w + qx) * 3) as usize;
            let mut s = 0.0;
            for c in 0..3 {
                let d = p.data[a + c] - p.data[b + c];
                s += d * d;
            }
            diff[(y * w + x) as usize] = s;
        }
    }
}

/// Horizontal box sums of `diff` (width `pw`) over 2 r + 1 pixels, for the
/// `dw` columns centred on padded columns r..r + dw.
fn box_rows(diff: &[f32], pw: usize, ph: usize, dw: usize, rows: &mut [f32]) {
    let r = PATCH_RADIUS;
    for y in 0..ph {
        let line = &diff[y * pw..(y + 1) * pw];
        let mut sum: f32 = line[..2 * r + 1].iter().sum();
        rows[y * dw] = sum;
        for x in 1..dw {
            sum += line[x + 2 * r] - line[x - 1];
            rows[y * dw + x] = sum;
        }
    }
}

/// The (2 r + 1)² box sum centred on distance-grid pixel (x, y), i.e. padded
/// pixel (x + r, y + r), from the horizontal sums.
fn box_column(rows: &[f32], dw: usize, x: usize, y: usize) -> f32 {
    let mut s = 0.0;
    for dy in 0..=2 * PATCH_RADIUS {
        s += rows[(y + dy) * dw + x];
    }
    s
}
