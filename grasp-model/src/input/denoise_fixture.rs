//! Test images of the denoiser, shared by its unit tests and the
//! `bench_denoise` example: a smooth colour ramp with a sharp-edged square
//! (content the noise estimator must not mistake for noise and the filter
//! must keep), and seeded Gaussian noise (splitmix64 and Box-Muller, so
//! that neither needs a crate).

use image::RgbImage;

/// The ramp with a square in its middle third, `w` x `h`.
pub fn scene(w: u32, h: u32) -> RgbImage {
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

/// `img` plus Gaussian noise of `sigma` (full scale), seeded.
pub fn noisy(img: &RgbImage, sigma: f32, seed: u64) -> RgbImage {
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
