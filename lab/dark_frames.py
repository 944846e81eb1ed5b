"""Frames too dark to read (issue 41): how many frames of each test set have
a near-black crop, and the FC recipe's per-video accuracy when frames whose
crop is darker than a threshold do not vote.

    lab/vote-rules.sh MAIN_OUT                      # the per-frame dumps
    .venv/bin/python lab/dark_frames.py MAIN_OUT [SET...]

A frame's darkness is the 95th percentile of the luminance (0-255) of the
square that the recipe reads, 18.3 degrees through the frame's own focal
length (sequence.json). The vote is the report's majority rule
(lab/vote_rules.py), pooled over the dumps' seeds.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).parent))
from vote_rules import PRESHAPES, majority  # noqa: E402

ANGLE_DEG = 18.3
THRESHOLDS = [0, 5, 10, 20, 30, 45]
SETS = ["world_foreign_ycb_reach", "world_reach", "default", "unseen_look", "from_ground"]


def crop_darkness(video_dir):
    """The 95th percentile of each frame's crop luminance, in frame order."""
    plan = json.loads((video_dir / "sequence.json").read_text())["plan"]
    k = plan["intrinsics"]
    side = min(2 * k["fx"] * math.tan(math.radians(ANGLE_DEG / 2)), k["width"], k["height"])
    y0, x0, s = round((k["height"] - side) / 2), round((k["width"] - side) / 2), round(side)
    out = []
    for png in sorted(video_dir.glob("*.png")):
        rgb = np.asarray(Image.open(png).convert("RGB"), dtype=np.float32)
        lum = rgb[y0 : y0 + s, x0 : x0 + s] @ np.array([0.2126, 0.7152, 0.0722])
        out.append(np.percentile(lum, 95))
    return np.array(out)


def main():
    out = Path(sys.argv[1])
    sets = sys.argv[2:] or SETS
    dumps = sorted((out / "lab/predictions").glob("fc-*.jsonl"))
    seeds = sorted({p.name.split("-")[1] for p in dumps})
    print("| dark frames left out (crop p95 below) | " + " | ".join(sets) + " |")
    print("|---" * (len(sets) + 1) + "|")
    darkness = {}
    for threshold in THRESHOLDS:
        cells = []
        for name in sets:
            right = videos = dropped = frames = 0
            for seed in seeds:
                for line in open(out / f"lab/predictions/fc-{seed}-{name}.jsonl"):
                    video = json.loads(line)
                    probs = np.array(video["probs"])
                    key = (name, video["id"])
                    if key not in darkness:
                        darkness[key] = crop_darkness(out / "data" / f"test-{name}" / video["id"])
                    # The lead-in frames the evaluation trims are the first ones.
                    keep = darkness[key][len(darkness[key]) - len(probs) :] >= threshold
                    frames += len(keep)
                    dropped += int((~keep).sum())
                    guess = majority(probs[keep]) if keep.any() else None
                    right += guess == PRESHAPES.index(video["preshape"])
                    videos += 1
            cells.append(f"{100 * right / videos:.1f} ({100 * dropped / frames:.0f} % out)")
        print(f"| {threshold} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
