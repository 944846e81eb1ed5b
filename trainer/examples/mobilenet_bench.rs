//! Speed of MobileNetV2 feature extraction in candle (eval mode): images/s at
//! a batch size and batch-1 latency (median, p99). Prints one JSON line, so
//! that scripts/bench_torch.py can put it next to PyTorch's numbers.
//!
//!   cargo run --release -p trainer --example mobilenet_bench -- --threads 2

use std::time::Instant;

use anyhow::Context;
use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use clap::Parser;
use trainer::model::{weights, MobileNetV2, MobileNetV2Config};

/// Benchmark candle MobileNetV2 feature extraction on the CPU.
#[derive(Parser)]
struct Args {
    /// Worker threads (rayon; candle and the custom kernels share the pool).
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Batch size of the throughput measurement.
    #[arg(long, default_value_t = 32)]
    batch: usize,
    /// Input height and width.
    #[arg(long, default_value_t = 224)]
    size: usize,
    #[arg(long, default_value_t = 1.0)]
    width_mult: f64,
    /// Timed batches for throughput (after 2 warm-up batches).
    #[arg(long, default_value_t = 10)]
    iters: usize,
    /// Timed batch-1 calls for latency (after 10 warm-up calls).
    #[arg(long, default_value_t = 200)]
    latency_iters: usize,
    /// Optional checkpoint (.pth or .safetensors); random weights otherwise.
    #[arg(long)]
    weights: Option<std::path::PathBuf>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .build_global()
        .context("setting up the thread pool")?;
    let dev = Device::Cpu;
    let cfg = MobileNetV2Config {
        width_mult: args.width_mult,
        ..Default::default()
    };
    let varmap = VarMap::new();
    let vb = match &args.weights {
        Some(p) => weights::var_builder(p, &dev)?,
        None => VarBuilder::from_varmap(&varmap, DType::F32, &dev),
    };
    let model = MobileNetV2::new(vb, &cfg)?;

    let x = Tensor::randn(0f32, 1.0, (args.batch, 3, args.size, args.size), &dev)?;
    for _ in 0..2 {
        model.features(&x, false)?;
    }
    let start = Instant::now();
    for _ in 0..args.iters {
        model.features(&x, false)?;
    }
    let secs = start.elapsed().as_secs_f64();
    let images_per_s = (args.batch * args.iters) as f64 / secs;

    let x1 = Tensor::randn(0f32, 1.0, (1, 3, args.size, args.size), &dev)?;
    for _ in 0..10 {
        model.features(&x1, false)?;
    }
    let mut ms = Vec::with_capacity(args.latency_iters);
    for _ in 0..args.latency_iters {
        let t = Instant::now();
        model.features(&x1, false)?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    let pct = |p: f64| ms[((ms.len() - 1) as f64 * p).round() as usize];
    let report = serde_json::json!({
        "framework": "candle",
        "threads": args.threads,
        "batch": args.batch,
        "size": args.size,
        "width_mult": args.width_mult,
        "images_per_s": images_per_s,
        "latency_ms_median": pct(0.5),
        "latency_ms_p99": pct(0.99),
    });
    println!("{report}");
    Ok(())
}
