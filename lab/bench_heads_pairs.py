"""Side-by-side runs of the heads' epoch benchmark: `grasp-train bench-heads`
(a lab command: built with `--features lab`)
and its PyTorch peer (lab/bench_torch_heads.py) alternately, `--rounds`
times, with the same workload and threads. Prints every pair and the median
of the per-pair ratios (PyTorch seconds / candle seconds; above 1 means candle
is faster). Alternating pairs keeps a shared machine's drifting speed out of
the ratio.

Usage (the PyTorch side runs in the environment lab/bench-env.sh makes):
  P=$(lab/bench-env.sh | tail -n1)
  cargo build --release -p trainer --features lab   # bench-heads
  $P lab/bench_heads_pairs.py --head lstm --rounds 5 \
      --candle target/release/grasp-train --torch-python $P
"""

import argparse
import json
import statistics
import subprocess
from pathlib import Path

WORKLOADS = {
    "fc": ["--epochs", "9"],
    "lstm": ["--sequences", "100", "--val-sequences", "20", "--batch", "32", "--epochs", "5"],
}


def median_epoch(cmd):
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])["median_epoch_s"]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--head", choices=sorted(WORKLOADS), default="lstm")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--candle", default="target/release/grasp-train")
    p.add_argument("--torch-python", default=".venv-bench/bin/python", help="see lab/bench-env.sh")
    args = p.parse_args()
    work = ["--head", args.head, *WORKLOADS[args.head]]
    torch_script = str(Path(__file__).with_name("bench_torch_heads.py"))
    pairs = []
    for i in range(args.rounds):
        c = median_epoch([args.candle, "--threads", str(args.threads), "bench-heads", *work])
        t = median_epoch([args.torch_python, torch_script, *work, "--threads", str(args.threads)])
        pairs.append((c, t))
        print(f"round {i + 1}: candle {c:.4f} s  pytorch {t:.4f} s  ratio {t / c:.2f}", flush=True)
    ratios = [t / c for c, t in pairs]
    print(
        json.dumps(
            {
                "head": args.head,
                "candle_median_s": round(statistics.median(c for c, _ in pairs), 4),
                "pytorch_median_s": round(statistics.median(t for _, t in pairs), 4),
                "median_ratio": round(statistics.median(ratios), 2),
                "min_ratio": round(min(ratios), 2),
                "max_ratio": round(max(ratios), 2),
            }
        )
    )


if __name__ == "__main__":
    main()
