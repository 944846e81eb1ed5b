//! Sensor denoising of the backbone's input square: the noise level of each
//! image is estimated from the image itself (Immerkaer's Laplacian-difference
//! estimator), then removed by non-local means with a filtering strength
//! proportional to it. A camera noisier than training's then reaches the
//! frozen backbone about as clean as training's frames, and a clean frame
//! passes nearly unchanged (EXPERIMENTS-archive.md, section 21).
//!
//! Non-local means (Buades, Coll and Morel 2005; the fast per-offset form of
//! Darbon et al. 2008): every pixel becomes a weighted mean of the pixels in
//! a search window around it, each weighted by how alike the patches around
//! the two are, exp(-max(d² - 2σ², 0) / h²), with d² the mean squared
//! difference of the two patches over their pixels and channels.

use image::RgbImage;

use crate::ops::cpu::simd_dispatch;

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
    // The mask's responses to 8-bit pixels are integers, so their absolute
    // sum is exact in integers (and was exact in the f64 of the first
    // version: the same estimate to the bit). Channels are interleaved, so
    // the horizontal neighbours of raw[i] are raw[i -+ 3] and one pass over
    // a row serves all three channels.
    let raw = img.as_raw();
    let row = |y: usize| &raw[y * w * 3..(y + 1) * w * 3];
    let mut total = 0u64;
    for y in 1..h - 1 {
        total += laplacian_difference_row(row(y - 1), row(y), row(y + 1));
    }
    let total = total as f64;
    let count = 3.0 * 6.0 * ((w - 2) * (h - 2)) as f64;
    let sigma = (std::f64::consts::FRAC_PI_2).sqrt() * total / count / 255.0;
    sigma as f32
}

/// Sum over the inner pixels of a row of |1 -2 1| (x) |1 -2 1|, the
/// difference of two Laplacians, for all channels (`up`, `mid`, `down`: the
/// rows above, at and below, interleaved RGB).
fn laplacian_difference_row(up: &[u8], mid: &[u8], down: &[u8]) -> u64 {
    let n = mid.len();
    let line = |r: &[u8], i: usize| i32::from(r[i - 3]) - 2 * i32::from(r[i]) + i32::from(r[i + 3]);
    (3..n - 3)
        .map(|i| (line(up, i) - 2 * line(mid, i) + line(down, i)).unsigned_abs() as u64)
        .sum()
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
///
/// Each pair's patch distance is computed once and serves both pixels (half
/// the window's offsets), from patch sums slid down the image in exact
/// integer arithmetic; blocks of pairs whose patches are all unlike (most
/// of a rendered frame) skip their exponentials and their sums. Rows are
/// worked in blocks of 16 floats, compiled
/// for AVX-512 or AVX2 when the CPU has them, without fused multiply-adds,
/// and two threads take alternate offsets whose sums are added in a fixed
/// order: the same result to the bit on any x86-64 CPU and thread count.
pub fn nl_means(img: &RgbImage, sigma: f32, h: f32) -> RgbImage {
    let (w, hgt) = (img.width() as usize, img.height() as usize);
    if w == 0 || hgt == 0 || h <= 0.0 || !h.is_finite() || !sigma.is_finite() {
        return img.clone();
    }
    let planes = Planes::new(img, PATCH_RADIUS + SEARCH_RADIUS);
    let weighting = Weighting::new(sigma, h);
    // The two halves of the offsets on two threads, each into its own sums,
    // added in a fixed order: the result does not depend on the pool size.
    let (even, odd): (Vec<_>, Vec<_>) = half_window().partition(|&(i, _)| i % 2 == 0);
    let strip = |v: Vec<(usize, Offset)>| v.into_iter().map(|(_, o)| o).collect::<Vec<_>>();
    let (even, odd) = (strip(even), strip(odd));
    let (mut sums, other) = rayon::join(
        || {
            let mut s = Sums::centre(&planes);
            accumulate(&planes, &even, weighting, &mut s);
            s
        },
        || {
            let mut s = Sums::zero(planes.stride * hgt);
            accumulate(&planes, &odd, weighting, &mut s);
            s
        },
    );
    sums.add(&other);
    sums.image(w, hgt, planes.stride)
}

/// A search offset (dx, dy).
type Offset = (isize, isize);

/// The offsets of one half of the search window, numbered: each with dy > 0,
/// or dy = 0 and dx > 0. Its mirror image -o is served by the same patch
/// distances (d(p, p + o) = d(p + o, p)), and the centre weighs 1.
fn half_window() -> impl Iterator<Item = (usize, Offset)> {
    let s = SEARCH_RADIUS as isize;
    (0..=s)
        .flat_map(move |dy| (-s..=s).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| dy > 0 || dx > 0)
        .enumerate()
}

/// Row lengths are rounded up to this many floats (one AVX-512 vector), so
/// that the vectorised loops have no scalar tail; the extra lanes compute
/// values that are never read out.
const LANES: usize = 16;

/// Floats after the last padded row, for the rounded-up rows to read.
const SLACK: usize = 4 * LANES;

fn round_up(n: usize) -> usize {
    n.div_ceil(LANES) * LANES
}

/// The image in [0, 1] floats, one plane per channel, with `pad` mirrored
/// pixels on every side: rows of one channel are contiguous, so the loops
/// over them vectorise.
struct Planes {
    data: [Vec<f32>; 3],
    width: usize,
    pad: usize,
    /// Size of the unpadded image.
    w: usize,
    h: usize,
    /// Row stride of the sums: `w` rounded up.
    stride: usize,
}

impl Planes {
    fn new(img: &RgbImage, pad: usize) -> Planes {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let (width, height) = (w + 2 * pad, h + 2 * pad);
        let raw = img.as_raw();
        let mut data = [(); 3].map(|_| vec![0f32; width * height + SLACK]);
        // Each padded column's source column, mirrored once for all rows.
        let columns: Vec<usize> = (0..width)
            .map(|x| mirror(x as isize - pad as isize, w))
            .collect();
        for y in 0..height {
            let source_row = mirror(y as isize - pad as isize, h) * w;
            for (x, &sx) in columns.iter().enumerate() {
                let i = (source_row + sx) * 3;
                for (c, plane) in data.iter_mut().enumerate() {
                    plane[y * width + x] = f32::from(raw[i + c]);
                }
            }
        }
        Planes {
            data,
            width,
            pad,
            w,
            h,
            stride: round_up(w),
        }
    }

    /// `len` values of each channel from image pixel (x, y) on (x and y
    /// may lie in the padding).
    #[inline(always)]
    fn row(&self, x: isize, y: isize, len: usize) -> [&[f32]; 3] {
        let start =
            (y + self.pad as isize) as usize * self.width + (x + self.pad as isize) as usize;
        [0, 1, 2].map(|c| &self.data[c][start..start + len])
    }
}

/// exp(-max(d² - 2σ², 0) / h²) from a patch's summed squared differences.
#[derive(Clone, Copy)]
struct Weighting {
    /// 1 / (channels x patch pixels): the sum to the mean d².
    per_value: f32,
    two_sigma2: f32,
    inv_h2: f32,
}

impl Weighting {
    /// For `sigma` and `h` as fractions of full scale (the planes hold
    /// grey levels).
    fn new(sigma: f32, h: f32) -> Weighting {
        let side = 2 * PATCH_RADIUS + 1;
        let (sigma, h) = (sigma * 255.0, h * 255.0);
        Weighting {
            per_value: 1.0 / (3 * side * side) as f32,
            two_sigma2: 2.0 * sigma * sigma,
            inv_h2: 1.0 / (h * h),
        }
    }

    /// The exponent of the weight of a patch pair whose squared
    /// differences sum to `sum`: max(d² - 2σ², 0) / h².
    #[inline(always)]
    fn exponent(self, sum: f32) -> f32 {
        (sum * self.per_value - self.two_sigma2).max(0.0) * self.inv_h2
    }

    /// The weight for `exponent` x; 0 where it is negligible. Branch-free,
    /// so that a row vectorises.
    #[inline(always)]
    fn of(x: f32) -> f32 {
        let e = exp_neg(x);
        if x > NEGLIGIBLE {
            0.0
        } else {
            e
        }
    }
}

/// e^-x for x in [0, 12] (x outside is clamped to it; NaN counts as 0),
/// relative error below 2e-7 (2 ulp): x = n ln 2 + g with |g| <= ln 2 / 2,
/// e^-g by its Taylor series to g^7, 2^-n from the exponent bits.
/// `f32::exp` is a library call, which does not vectorise.
#[inline(always)]
fn exp_neg(x: f32) -> f32 {
    // Not `clamp`, which passes NaN through.
    #[allow(clippy::manual_clamp)]
    let x = x.max(0.0).min(NEGLIGIBLE);
    // SAFETY: x is in [0, 12], so the value converted is in [0.5, 17.9]:
    // finite and in range. Unchecked, the conversion is one instruction;
    // `as` adds saturation and NaN checks that took up to 40 % of the
    // filter's time (BENCHMARKS.md, "The crop denoiser").
    let n: i32 = unsafe { (x * std::f32::consts::LOG2_E + 0.5).to_int_unchecked() };
    // ln 2 in two parts (Cody and Waite): n x LN2_HI is exact for n < 2^15,
    // so g keeps the precision that x - n ln 2 in one step would lose.
    let g = (x - n as f32 * LN2_HI) - n as f32 * LN2_LO;
    // Horner's scheme in -g over the coefficients 1/k!.
    let mut p = INV_FACTORIALS[7];
    for k in (0..7).rev() {
        p = p * -g + INV_FACTORIALS[k];
    }
    p * f32::from_bits(((127 - n) << 23) as u32)
}

/// ln 2 = LN2_HI + LN2_LO, LN2_HI with 9 significant bits.
const LN2_HI: f32 = 355.0 / 512.0;
const LN2_LO: f32 = -2.121_944_4e-4;

/// 1/k! for k = 0..7.
const INV_FACTORIALS: [f32; 8] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
];

/// Weighted sums of the neighbours of each pixel, per channel, and of their
/// weights.
struct Sums {
    chan: [Vec<f32>; 3],
    weight: Vec<f32>,
}

impl Sums {
    fn zero(len: usize) -> Sums {
        Sums {
            chan: [(); 3].map(|_| vec![0f32; len]),
            weight: vec![0f32; len],
        }
    }

    /// The centre offset: every pixel counts itself with weight 1 (its
    /// patch distance to itself is 0).
    fn centre(p: &Planes) -> Sums {
        let mut s = Sums::zero(p.stride * p.h);
        for y in 0..p.h {
            let src = p.row(0, y as isize, p.w);
            for (sum, src) in s.chan.iter_mut().zip(src) {
                sum[y * p.stride..y * p.stride + p.w].copy_from_slice(src);
            }
        }
        s.weight.fill(1.0);
        s
    }

    fn add(&mut self, other: &Sums) {
        for (a, b) in self.chan.iter_mut().zip(&other.chan) {
            a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
        }
        let w = self.weight.iter_mut().zip(&other.weight);
        w.for_each(|(a, b)| *a += b);
    }

    /// The weighted means of the rows of `stride` sums, `w` x `h` pixels.
    fn image(&self, w: usize, h: usize, stride: usize) -> RgbImage {
        let mut out = RgbImage::new(w as u32, h as u32);
        for (j, px) in out.pixels_mut().enumerate() {
            let i = j / w * stride + j % w;
            for c in 0..3 {
                // A mean of values in [0, 255]: rounding half up is
                // rounding, without `f32::round`'s library call.
                let v = self.chan[c][i] / self.weight[i];
                px.0[c] = (v + 0.5).clamp(0.0, 255.0) as u8;
            }
        }
        out
    }
}

simd_dispatch! {
/// Adds the neighbours at every offset of `offsets` and at its mirror image
/// to `sums`, on the widest vector unit this CPU has.
fn accumulate(p: &Planes, offsets: &[Offset], wt: Weighting, sums: &mut Sums) {
    let mut scratch = Scratch::default();
    for &o in offsets {
        accumulate_offset(p, o, wt, &mut scratch, sums);
    }
}
}

/// Buffers reused across offsets.
#[derive(Default)]
struct Scratch {
    diff: Vec<f32>,
    column: Vec<f32>,
    weight: Vec<f32>,
}

/// One offset o of the half window: the weight of every pair (q, q + o)
/// with q or q + o in the image, from the squared differences box-summed
/// over the patch; then each image pixel p gains p + o (weight of q = p)
/// and p - o (weight of q = p - o).
#[inline(always)]
fn accumulate_offset(
    p: &Planes,
    (ox, oy): Offset,
    wt: Weighting,
    s: &mut Scratch,
    sums: &mut Sums,
) {
    let (w, h) = (p.w as isize, p.h as isize);
    // q spans the image and the image shifted by -o.
    let (x0, y0) = (0.min(-ox), -oy);
    let (x1, y1) = (w.max(w - ox), h);
    let r = PATCH_RADIUS as isize;
    // Rows of weights are read from |o| on (`skip` below), a stride long:
    // longer than the x1 - x0 pairs, rounded up (at most SLACK past the
    // last padded row for the squared differences' reads).
    let (n, stride) = (round_up(ox.unsigned_abs() + p.stride), p.stride);
    debug_assert!(n >= (x1 - x0) as usize);
    let dw = n + LANES;
    let rows = (y1 - y0 + 2 * r) as usize;
    squared_differences(p, (x0 - r, y0 - r), (ox, oy), (dw, rows), &mut s.diff);
    s.column.resize(dw, 0.0);
    s.weight.resize(n, 0.0);
    let side = 2 * PATCH_RADIUS + 1;
    column_sums(&s.diff[..side * dw], dw, &mut s.column);
    for qy in y0..y1 {
        if qy > y0 {
            // The band moves down a row: exact, as every term is an integer.
            let top = (qy - y0 - 1) as usize * dw;
            let leaving = &s.diff[top..top + dw];
            let entering = &s.diff[top + side * dw..top + (side + 1) * dw];
            slide_column_sums(leaving, entering, &mut s.column);
        }
        row_weights(&s.column, wt, &mut s.weight);
        let wrow = &s.weight[..];
        if (0..h).contains(&qy) {
            // p = q: the neighbour p + o.
            let i = qy as usize * stride;
            let skip = (-x0) as usize;
            gather(
                &wrow[skip..skip + stride],
                p.row(ox, qy + oy, stride),
                sums,
                i,
            );
        }
        if (0..h).contains(&(qy + oy)) {
            // p = q + o: the neighbour p - o.
            let i = (qy + oy) as usize * stride;
            let skip = (-ox - x0) as usize;
            gather(&wrow[skip..skip + stride], p.row(-ox, qy, stride), sums, i);
        }
    }
}

/// `diff` = rows x width squared colour differences between image pixel
/// `from` + (i, j) and the same plus `o`.
#[inline(always)]
fn squared_differences(
    p: &Planes,
    from: Offset,
    o: Offset,
    (width, rows): (usize, usize),
    diff: &mut Vec<f32>,
) {
    diff.resize(width * rows, 0.0);
    for (j, out) in diff.chunks_exact_mut(width).enumerate() {
        let y = from.1 + j as isize;
        let [a0, a1, a2] = p.row(from.0, y, width);
        let [b0, b1, b2] = p.row(from.0 + o.0, y + o.1, width);
        for i in 0..width {
            let (d0, d1, d2) = (a0[i] - b0[i], a1[i] - b1[i], a2[i] - b2[i]);
            out[i] = d0 * d0 + d1 * d1 + d2 * d2;
        }
    }
}

/// `column[i]` = the sum of the (2 r + 1) rows of `band` at i.
#[inline(always)]
fn column_sums(band: &[f32], width: usize, column: &mut [f32]) {
    column.copy_from_slice(&band[..width]);
    for line in band.chunks_exact(width).skip(1) {
        column.iter_mut().zip(line).for_each(|(c, v)| *c += v);
    }
}

/// The column sums of the band one row down: minus the row `leaving`, plus
/// the row `entering`. The planes hold whole grey levels, so squared
/// differences and their sums are integers below 2^24 (5 x 5 x 3 x 255²
/// = 4 876 875): exact in f32, and sliding carries no rounding error down
/// the image.
#[inline(always)]
fn slide_column_sums(leaving: &[f32], entering: &[f32], column: &mut [f32]) {
    let rows = leaving.iter().zip(entering);
    column
        .iter_mut()
        .zip(rows)
        .for_each(|(c, (l, e))| *c += e - l);
}

/// `weight[i]` = the weight of the patch sum over columns i..i + 2 r + 1
/// (`weight.len()` a multiple of LANES).
#[inline(always)]
fn row_weights(column: &[f32], wt: Weighting, weight: &mut [f32]) {
    for (b, out) in weight.chunks_exact_mut(LANES).enumerate() {
        let i = b * LANES;
        let mut sum = lanes(column, i);
        for k in 1..2 * PATCH_RADIUS + 1 {
            let c = lanes(column, i + k);
            (0..LANES).for_each(|l| sum[l] += c[l]);
        }
        let x = sum.map(|s| wt.exponent(s));
        // A block of unlike patches only (most blocks of a clean frame)
        // weighs 0 without the exponentials: the same zeros, sooner.
        if x.iter().all(|&x| x > NEGLIGIBLE) {
            out.fill(0.0);
        } else {
            (0..LANES).for_each(|l| out[l] = Weighting::of(x[l]));
        }
    }
}

/// Adds `weight[i]` x `src[c][i]` to row `start + i` of each channel's sums,
/// and the weight to the weight sums (`weight.len()` a multiple of LANES).
#[inline(always)]
fn gather(weight: &[f32], src: [&[f32]; 3], sums: &mut Sums, start: usize) {
    for b in (0..weight.len()).step_by(LANES) {
        let w = lanes(weight, b);
        // Adding zeros leaves the sums as they are, to the bit.
        if w.iter().all(|&w| w == 0.0) {
            continue;
        }
        for (sum, src) in sums.chan.iter_mut().zip(src) {
            let (mut s, v) = (lanes(sum, start + b), lanes(src, b));
            (0..LANES).for_each(|l| s[l] += w[l] * v[l]);
            sum[start + b..start + b + LANES].copy_from_slice(&s);
        }
        let mut s = lanes(&sums.weight, start + b);
        (0..LANES).for_each(|l| s[l] += w[l]);
        sums.weight[start + b..start + b + LANES].copy_from_slice(&s);
    }
}

/// A copy of `v[at..at + LANES]`. Blocks are worked on as such copies: with
/// every load before every store, the compiler needs no proof that the
/// slices are apart to vectorise, and a block has no scalar tail.
#[inline(always)]
fn lanes(v: &[f32], at: usize) -> [f32; LANES] {
    v[at..at + LANES]
        .try_into()
        .expect("a block of LANES floats")
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

#[cfg(test)]
mod reference;

#[cfg(test)]
#[path = "denoise_fixture.rs"]
mod fixture;

#[cfg(test)]
mod tests;
