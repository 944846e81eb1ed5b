"""The crop denoiser: ours (grasp-model's bench_denoise example) next to
scikit-image's non-local means, in alternating rounds.

Both run the same filter on the same 94 x 94 crops: 5 x 5 patches, a 13 x
13 search window (patch_distance 6), mirrored edges, the noise sigma that
our estimator reads off the crop and h = 0.8 sigma, with the noise variance
subtracted from the patch distances (skimage's `sigma`), in skimage's fast
mode (the per-offset box-sum form ours uses too). skimage runs on one
thread; ours (`nl_means`, the filter without the estimate) once with one
rayon thread and once with two. Each round prints per-call times (median,
minimum, CPU time per call of all threads); the end prints the median CPU
times over rounds and the medians over rounds of the per-round ratios
skimage / ours, of CPU time (the work; the steadier measure on a shared
machine) and of the minimum wall time (what two threads buy).

  cargo build --release -p grasp-model --example bench_denoise
  .venv/bin/python lab/bench_denoise.py --rust target/release/examples/bench_denoise \
      [--frame FRAME.png ...]

Also prints the largest difference between the two filters' outputs, in
grey levels (for the same sigma and h).
"""

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

import numpy as np
from PIL import Image
from skimage.restoration import denoise_nl_means


def run_rust(args: argparse.Namespace, threads: int, out: str) -> dict:
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    cmd = [args.rust, "--iters", str(args.iters), "--size", str(args.size), "--save", out]
    if args.frame:
        cmd += ["--frame", *args.frame]
    lines = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
    return {r["input"]: r for r in map(json.loads, lines.splitlines())}


def run_skimage(path: str, sigma: float, iters: int) -> tuple[dict, np.ndarray]:
    img = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0

    def call() -> np.ndarray:
        return denoise_nl_means(
            img,
            patch_size=5,
            patch_distance=6,
            h=0.8 * sigma,
            sigma=sigma,
            fast_mode=True,
            channel_axis=-1,
        )

    for _ in range(3):
        call()
    times = []
    cpu = time.process_time()
    for _ in range(iters):
        t = time.perf_counter()
        out = call()
        times.append((time.perf_counter() - t) * 1e3)
    cpu_ms = (time.process_time() - cpu) * 1e3 / iters
    stats = {"p50": statistics.median(times), "min": min(times), "cpu": cpu_ms}
    return stats, out


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--rust", required=True, help="the bench_denoise example binary")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--iters", type=int, default=100)
    ap.add_argument("--size", type=int, default=94)
    ap.add_argument(
        "--frame", nargs="*", default=[], help="rendered frames: their centre squares too"
    )
    args = ap.parse_args()
    ratios: dict[tuple[str, int, str], list[float]] = {}
    cpu: dict[tuple[str, str], list[float]] = {}
    with tempfile.TemporaryDirectory() as out:
        for rnd in range(args.rounds):
            ours = {t: run_rust(args, t, out) for t in (1, 2)}
            for name, row in ours[1].items():
                sk, sk_out = run_skimage(os.path.join(out, f"{name}.png"), row["sigma"], args.iters)
                mine = np.asarray(
                    Image.open(os.path.join(out, f"{name}-denoised.png")), dtype=np.float64
                )
                diff = np.abs(np.round(sk_out * 255.0) - mine)
                print(
                    f"round {rnd + 1} {name}: sigma {row['sigma']:.4f}; "
                    + "; ".join(
                        f"ours {t} thread(s) p50 {r[name]['nl_means_ms']['p50']:.2f} ms, "
                        f"min {r[name]['nl_means_ms']['min']:.2f}, CPU {r[name]['nl_means_ms']['cpu']:.2f}"
                        for t, r in ours.items()
                    )
                    + f"; skimage p50 {sk['p50']:.2f} ms, min {sk['min']:.2f}, CPU {sk['cpu']:.2f}"
                    + f"; outputs differ by max {diff.max():.0f}, mean {diff.mean():.3f} grey levels",
                    flush=True,
                )
                cpu.setdefault((name, "skimage"), []).append(sk["cpu"])
                for t, r in ours.items():
                    cpu.setdefault((name, f"ours-{t}"), []).append(r[name]["nl_means_ms"]["cpu"])
                    mine_t = r[name]["nl_means_ms"]
                    ratios.setdefault((name, t, "CPU time"), []).append(sk["cpu"] / mine_t["cpu"])
                    ratios.setdefault((name, t, "minimum wall time"), []).append(
                        sk["min"] / mine_t["min"]
                    )
    for (name, who), v in sorted(cpu.items()):
        print(f"{name} {who}: median CPU {statistics.median(v):.2f} ms per call")
    for (name, t, what), v in sorted(ratios.items()):
        print(
            f"{name}: skimage / ours ({t} thread(s)), {what}, median of rounds "
            f"{statistics.median(v):.1f} (range {min(v):.1f} to {max(v):.1f})"
        )


if __name__ == "__main__":
    main()
