//! Sensor denoising of the backbone's input square: the noise level of each
//! image is estimated from the image itself (Immerkaer's Laplacian-difference
//! estimator), then removed by non-local means with a filtering strength
//! proportional to it. A camera noisier than training's then reaches the
//! frozen backbone about as clean as training's frames, and a clean frame
//! passes nearly unchanged (EXPERIMENTS.md, section 21).
//!
//! Non-local means (Buades, Coll and Morel 2005; the fast per-offset form of
//! Darbon et al. 2008): every pixel becomes a weighted mean of the pixels in
//! a search window around it, each weighted by how alike the patches around
//! the two are, exp(-max(d² - 2σ², 0) / h²), with d² the mean squared
//! difference of the two patches over their pixels and channels.

use image::RgbImage;

/// Half side of the compared patches (5 x 5).
const PATCH_RADIUS: usize = 2;
/// Half side of the search window (13 x 13).
const SEARCH_RADIUS: usize = 6;
/// Filtering strength h as a multiple of the estimated noise sigma.
const STRENGTH: f32 = 0.8;
/// Patches this unlike (weights below exp(-12), 6e-6) are skipped: they
/// cannot move a pixel by a measurable amount, and most pairs are such.
const NEGLIGIBLE: f32 = 12.0;
/// Below this estimated sigma (a fraction of full scale, about a quarter of
/// a grey level) the image is returned unchanged.
const MIN_SIGMA: f32 = 1e-3;

/// Standard deviation of additive Gaussian noise in `img`, as a fraction of
/// full scale, averaged over the channels (Immerkaer 1996: the mean absolute
/// response to the difference of two Laplacians, which cancels smooth image
/// content). Images smaller than 3 x 3 have no estimate: 0.
pub fn noise_sigma(img: &RgbImage) -> f32 {
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

/// `img` with its sensor noise removed: non-local means at a strength of
/// 0.8 x the estimated noise sigma; unchanged when the estimate is below
/// about a quarter of a grey level.
pub fn denoise(img: &RgbImage) -> RgbImage {
    let sigma = noise_sigma(img);
    if sigma < MIN_SIGMA {
        return img.clone();
    }
    nl_means(img, sigma, STRENGTH * sigma)
}

/// Non-local means of `img` for noise `sigma` and strength `h` (both
/// fractions of full scale), 5 x 5 patches in a 13 x 13 window, edges
/// mirrored.
pub fn nl_means(img: &RgbImage, sigma: f32, h: f32) -> RgbImage {
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

/// Index `i` mirrored into 0..n without repeating the edge (..., 2, 1, 0, 1,
/// 2, ...), folding again for paddings wider than the image.
fn mirror(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let m = i.rem_euclid(period);
    (if m < n as isize { m } else { period - m }) as usize
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth colour ramp with a sharp-edged square: content the
    /// estimator must not mistake for noise and the filter must keep.
    fn scene(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let inside = (w / 3..2 * w / 3).contains(&x) && (h / 3..2 * h / 3).contains(&y);
            let base = (40 + x * 120 / w) as u8;
            if inside {
                image::Rgb([200, 60, base])
            } else {
                image::Rgb([base, (60 + y * 100 / h) as u8, 90])
            }
        })
    }

    /// `img` plus Gaussian noise of `sigma` (full scale), seeded
    /// (splitmix64 and Box-Muller, so that the test needs no crate).
    fn noisy(img: &RgbImage, sigma: f32, seed: u64) -> RgbImage {
        let mut state = seed;
        let mut uniform = move || {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut out = img.clone();
        for v in out.iter_mut() {
            let (u1, u2) = (uniform().max(1e-12), uniform());
            let n = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            *v = (f64::from(*v) + 255.0 * f64::from(sigma) * n)
                .round()
                .clamp(0.0, 255.0) as u8;
        }
        out
    }

    fn rmse(a: &RgbImage, b: &RgbImage) -> f32 {
        let n = a.as_raw().len() as f32;
        let s: f32 = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(x, y)| (f32::from(*x) - f32::from(*y)).powi(2))
            .sum();
        (s / n).sqrt() / 255.0
    }

    #[test]
    fn the_estimate_follows_the_added_noise() {
        let clean = scene(96, 80);
        assert!(noise_sigma(&clean) < 0.004, "{}", noise_sigma(&clean));
        for sigma in [0.01, 0.02, 0.04] {
            let est = noise_sigma(&noisy(&clean, sigma, 7));
            assert!(
                (est - sigma).abs() < 0.15 * sigma,
                "sigma {sigma}: estimated {est}"
            );
        }
    }

    #[test]
    fn denoising_brings_a_noisy_image_closer_to_the_clean_one() {
        let clean = scene(64, 64);
        for sigma in [0.02, 0.04] {
            let dirty = noisy(&clean, sigma, 3);
            let before = rmse(&dirty, &clean);
            let after = rmse(&denoise(&dirty), &clean);
            assert!(after < 0.5 * before, "sigma {sigma}: {before} -> {after}");
        }
    }

    #[test]
    fn a_clean_image_passes_unchanged() {
        let clean = scene(40, 30);
        assert_eq!(denoise(&clean), clean);
    }

    #[test]
    fn constant_images_stay_constant() {
        let flat = RgbImage::from_pixel(17, 9, image::Rgb([10, 128, 250]));
        assert_eq!(nl_means(&flat, 0.03, 0.024), flat);
    }

    #[test]
    fn degenerate_sizes_do_not_panic() {
        for (w, h) in [(1, 1), (1, 7), (7, 1), (2, 2), (3, 3)] {
            let img = noisy(
                &RgbImage::from_pixel(w, h, image::Rgb([90, 90, 90])),
                0.05,
                1,
            );
            let out = denoise(&img);
            assert_eq!(out.dimensions(), (w, h));
            let _ = noise_sigma(&img);
        }
        let empty = RgbImage::new(0, 0);
        assert_eq!(nl_means(&empty, 0.02, 0.016).dimensions(), (0, 0));
    }

    #[test]
    fn mirroring_folds_back_into_the_image() {
        assert_eq!(
            (-3..8).map(|i| mirror(i, 4)).collect::<Vec<_>>(),
            vec![3, 2, 1, 0, 1, 2, 3, 2, 1, 0, 1]
        );
        assert_eq!(mirror(-5, 1), 0);
    }
}
