//! Time of the crop denoiser alone (`input::denoise`), per call, on the
//! crop the shipped checkpoint denoises: 94 x 94 px (18.3 degrees of a 224
//! px frame). Two inputs: a smooth scene with camera-like Gaussian noise,
//! and a crop of `hannes-run bench`'s synthetic frames (noise-like, the
//! filter's worst case before it became branch-free).
//!
//!   cargo run --release -p grasp-model --example bench_denoise -- --iters 200
//!
//! Prints one JSON line per input. `--save DIR` also writes each input and
//! its denoised image as PNG, for `lab/bench_denoise.py` to run the
//! same work in scikit-image and compare.

use std::time::Instant;

#[path = "../src/input/denoise_fixture.rs"]
mod fixture;
use fixture::{noisy, scene};

use clap::Parser;
use grasp_model::input::denoise::{denoise, nl_means, noise_sigma};
use image::RgbImage;

#[derive(Parser)]
struct Args {
    /// Side of the square crop in pixels.
    #[arg(long, default_value_t = 94)]
    size: u32,
    /// Timed calls per input (after 5 untimed ones).
    #[arg(long, default_value_t = 200)]
    iters: usize,
    /// Gaussian noise added to the scene, as a fraction of full scale.
    #[arg(long, default_value_t = 0.02)]
    noise: f32,
    /// Write the inputs here as `<name>.png`.
    #[arg(long)]
    save: Option<std::path::PathBuf>,
    /// Also time the centre square of these images (rendered or recorded
    /// frames: the input the filter meets in use).
    #[arg(long, num_args = 1..)]
    frame: Vec<std::path::PathBuf>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let mut inputs = vec![
        (
            "scene".to_string(),
            noisy(&scene(args.size, args.size), args.noise, 7),
        ),
        ("bench_frame".to_string(), bench_frame_crop(args.size)),
    ];
    for (i, path) in args.frame.iter().enumerate() {
        let img = image::open(path)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
            .to_rgb8();
        inputs.push((format!("frame_{i}"), centre_square(&img, args.size)));
    }
    for (name, img) in &inputs {
        if let Some(dir) = &args.save {
            std::fs::create_dir_all(dir)?;
            img.save(dir.join(format!("{name}.png")))?;
            denoise(img).save(dir.join(format!("{name}-denoised.png")))?;
        }
        let sigma = noise_sigma(img);
        let whole = time(args.iters, || denoise(img));
        let filter = time(args.iters, || nl_means(img, sigma, 0.8 * sigma));
        let line = serde_json::json!({
            "input": name,
            "size": args.size,
            "sigma": sigma,
            "iters": args.iters,
            "threads": rayon::current_num_threads(),
            "denoise_ms": whole,
            "nl_means_ms": filter,
        });
        println!("{line}");
    }
    Ok(())
}

/// Minimum (the least disturbed by other processes), median, p99 and mean
/// of `iters` calls of `f`, in ms, and the process's CPU time per call (all
/// threads; on a shared machine the steadier measure).
fn time<T>(iters: usize, mut f: impl FnMut() -> T) -> serde_json::Value {
    for _ in 0..5 {
        std::hint::black_box(f());
    }
    let cpu = cpu_seconds();
    let mut ms: Vec<f64> = (0..iters.max(1))
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(f());
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let cpu_ms = cpu
        .zip(cpu_seconds())
        .map(|(a, b)| (b - a) * 1e3 / ms.len() as f64);
    let mean = ms.iter().sum::<f64>() / ms.len() as f64;
    ms.sort_by(f64::total_cmp);
    let rank = |q: f64| ms[((q * ms.len() as f64).ceil() as usize).clamp(1, ms.len()) - 1];
    serde_json::json!({
        "min": ms[0], "p50": rank(0.5), "p99": rank(0.99), "mean": mean, "cpu": cpu_ms,
    })
}

/// User plus system CPU time of this process (Linux: /proc/self/stat, in
/// clock ticks of 10 ms, so time many calls); None elsewhere.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are the
    // 14th and 15th of the line.
    let rest = &stat[stat.rfind(')')? + 2..];
    let mut fields = rest.split_whitespace().skip(11);
    let utime: f64 = fields.next()?.parse().ok()?;
    let stime: f64 = fields.next()?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// The centre `n` x `n` of `img` (all of it when smaller).
fn centre_square(img: &RgbImage, n: u32) -> RgbImage {
    let (w, h) = (n.min(img.width()), n.min(img.height()));
    let (x, y) = ((img.width() - w) / 2, (img.height() - h) / 2);
    image::imageops::crop_imm(img, x, y, w, h).to_image()
}

/// The centre `n` x `n` of `hannes-run bench`'s first synthetic 224 px frame
/// (the pattern of `hannes-run bench`'s synthetic frames).
fn bench_frame_crop(n: u32) -> RgbImage {
    let off = (224 - n.min(224)) / 2;
    RgbImage::from_fn(n, n, |x, y| {
        let (x, y) = (x + off, y + off);
        let v = (x * 7 + y * 13) % 256;
        image::Rgb([v as u8, (255 - v) as u8, ((x ^ y) % 256) as u8])
    })
}
