"""MobileNetV2 feature-extraction speed: PyTorch (torchvision) next to candle.

Measures torchvision's mobilenet_v2 in eval mode under torch.inference_mode
(features + global average pool, the same work as the candle model's
`features`): images/s at a batch size and batch-1 latency (median, p99).
With --candle BIN it then runs the candle benchmark binary with the same
settings and prints both, with candle/torch ratios, from one run.

  cargo build --release -p trainer --example mobilenet_bench
  /work/.venv-torch/bin/python scripts/bench_torch.py --threads 2 \
      --candle $CARGO_TARGET_DIR/release/examples/mobilenet_bench

Needs torch and torchvision (a separate venv; CI does not run this).
"""

import argparse
import json
import statistics
import subprocess
import time

import torch
import torchvision


def measure(args: argparse.Namespace) -> dict:
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    model = torchvision.models.mobilenet_v2(weights=None, width_mult=args.width_mult).eval()

    def features(x: torch.Tensor) -> torch.Tensor:
        return model.features(x).mean(dim=(2, 3))

    with torch.inference_mode():
        x = torch.randn(args.batch, 3, args.size, args.size)
        for _ in range(2):
            features(x)
        start = time.perf_counter()
        for _ in range(args.iters):
            features(x)
        images_per_s = args.batch * args.iters / (time.perf_counter() - start)

        x1 = torch.randn(1, 3, args.size, args.size)
        for _ in range(10):
            features(x1)
        ms = []
        for _ in range(args.latency_iters):
            t = time.perf_counter()
            features(x1)
            ms.append((time.perf_counter() - t) * 1e3)
    ms.sort()
    return {
        "framework": "torch " + torch.__version__,
        "threads": torch.get_num_threads(),
        "batch": args.batch,
        "size": args.size,
        "width_mult": args.width_mult,
        "images_per_s": images_per_s,
        "latency_ms_median": statistics.median(ms),
        "latency_ms_p99": ms[round((len(ms) - 1) * 0.99)],
    }


def run_candle(args: argparse.Namespace) -> dict:
    cmd = [args.candle]
    for flag in ("threads", "batch", "size", "width_mult", "iters", "latency_iters"):
        cmd += ["--" + flag.replace("_", "-"), str(getattr(args, flag))]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--batch", type=int, default=32)
    p.add_argument("--size", type=int, default=224)
    p.add_argument("--width-mult", type=float, default=1.0)
    p.add_argument("--iters", type=int, default=10)
    p.add_argument("--latency-iters", type=int, default=200)
    p.add_argument("--candle", help="path of the mobilenet_bench example binary")
    args = p.parse_args()

    rows = [measure(args)]
    if args.candle:
        rows.append(run_candle(args))
    for r in rows:
        print(json.dumps(r))
    if len(rows) == 2:
        t, c = rows
        print(f"threads {args.threads}, {args.size}x{args.size}, width {args.width_mult}")
        print(f"{'':24}{'torch':>10}{'candle':>10}{'candle/torch':>14}")
        for key, label in (
            ("images_per_s", f"images/s (batch {args.batch})"),
            ("latency_ms_median", "batch-1 median ms"),
            ("latency_ms_p99", "batch-1 p99 ms"),
        ):
            print(f"{label:24}{t[key]:10.2f}{c[key]:10.2f}{c[key] / t[key]:14.2f}")


if __name__ == "__main__":
    main()
