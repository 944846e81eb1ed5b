//! Unit tests of `denoise`, apart so that the kernel file holds only the kernel.

use super::*;

use super::fixture::{noisy, scene};

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

/// Largest difference, in grey levels, between two images.
fn max_difference(a: &RgbImage, b: &RgbImage) -> u8 {
    let pairs = a.as_raw().iter().zip(b.as_raw());
    pairs.map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0)
}

#[test]
fn the_fast_filter_matches_the_reference_within_a_grey_level() {
    let sizes = [(1, 1), (1, 9), (9, 1), (2, 3), (5, 5), (12, 7), (13, 13)];
    let sizes = sizes.into_iter().chain([(17, 31), (40, 30), (94, 94)]);
    for (w, h) in sizes {
        // 0.003: about a rendered frame's noise, where most blocks of
        // pairs are negligible and skipped.
        for (sigma, seed) in [(0.003, 4), (0.02, 1), (0.08, 2), (0.3, 3)] {
            let img = noisy(&scene(w, h), sigma, seed);
            // The estimate where there is one, else the added noise.
            let est = Some(noise_sigma(&img)).filter(|s| *s > 0.0);
            let s = est.unwrap_or(sigma);
            for strength in [STRENGTH * s, 3.0 * s] {
                let fast = nl_means(&img, s, strength);
                let slow = reference::nl_means(&img, s, strength);
                let d = max_difference(&fast, &slow);
                assert!(
                    d <= 1,
                    "{w}x{h} sigma {sigma} h {strength}: {d} grey levels"
                );
                // Rounding flips only where a value sits near a half
                // level: a handful of 26 508 at 94 x 94.
                let pairs = fast.as_raw().iter().zip(slow.as_raw());
                let flipped = pairs.filter(|(a, b)| a != b).count();
                assert!(
                    flipped * 1000 <= fast.as_raw().len(),
                    "{w}x{h}: {flipped} differ"
                );
            }
        }
    }
}

#[test]
fn the_integer_estimate_is_the_reference_estimate_to_the_bit() {
    for (w, h) in [(3, 3), (4, 9), (17, 5), (94, 94)] {
        for sigma in [0.0, 0.02, 0.3] {
            let img = noisy(&scene(w, h), sigma, 5);
            assert_eq!(noise_sigma(&img), reference::noise_sigma(&img), "{w}x{h}");
        }
    }
}

#[test]
fn the_fast_exponential_is_within_2e_7_of_exp() {
    for i in 0..=120_000 {
        let x = i as f32 * 1e-4;
        let (fast, exact) = (exp_neg(x), (-f64::from(x)).exp());
        let rel = (f64::from(fast) - exact).abs() / exact;
        assert!(rel < 2e-7, "x {x}: {fast} vs {exact}");
    }
}

#[test]
fn the_fast_exponential_clamps_its_argument_to_its_range() {
    // Its unchecked conversion relies on the clamp.
    assert_eq!(exp_neg(-3.0), 1.0);
    assert_eq!(exp_neg(f32::NEG_INFINITY), 1.0);
    assert_eq!(exp_neg(f32::NAN), 1.0);
    assert_eq!(exp_neg(1e30), exp_neg(NEGLIGIBLE));
    assert_eq!(exp_neg(f32::INFINITY), exp_neg(NEGLIGIBLE));
    assert!((f64::from(exp_neg(NEGLIGIBLE)) - (-12f64).exp()).abs() < 1e-11);
}

#[test]
fn mirroring_folds_back_into_the_image() {
    assert_eq!(
        (-3..8).map(|i| mirror(i, 4)).collect::<Vec<_>>(),
        vec![3, 2, 1, 0, 1, 2, 3, 2, 1, 0, 1]
    );
    assert_eq!(mirror(-5, 1), 0);
}
