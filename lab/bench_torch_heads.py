"""PyTorch peer of `grasp-train bench-heads`: one training epoch of the FC or
LSTM head on generated cached features, with the same protocol (per-epoch
class downsampling, Adam lr 5e-4 with coupled L2 5e-4, cross-entropy, then a
validation pass over every frame).

Usage (in the environment lab/bench-env.sh makes):
  P=$(lab/bench-env.sh | tail -n1)
  $P lab/bench_torch_heads.py --head fc --threads 2
"""

import argparse
import json
import time

import torch
from torch import nn


def make_split(sequences, frames, dim, seed):
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(sequences * frames, dim, generator=g)
    cls = torch.arange(sequences) % 4
    labels = cls.repeat_interleave(frames).clone()
    labels.view(sequences, frames)[:, -2:] = 4
    return x, labels, cls


class LstmHead(nn.Module):
    def __init__(self, dim, hidden=256, classes=5):
        super().__init__()
        self.lstm = nn.LSTM(dim, hidden, batch_first=True)
        self.fc = nn.Linear(hidden, classes)

    def forward(self, x):
        return self.fc(self.lstm(x)[0])


def balanced(classes, g):
    groups = [torch.nonzero(classes == c).flatten() for c in range(5)]
    groups = [m for m in groups if len(m) > 0]
    n = min(len(m) for m in groups)
    picked = torch.cat([m[torch.randperm(len(m), generator=g)[:n]] for m in groups])
    return picked[torch.randperm(len(picked), generator=g)]


def epoch(args, model, opt, train, val, g):
    x, y, seq_cls = train
    frames, dim = args.frames, args.dim
    model.train()
    units = balanced(y if args.head == "fc" else seq_cls, g)
    for start in range(0, len(units), args.batch):
        idx = units[start : start + args.batch]
        if args.head == "fc":
            logits, target = model(x[idx]), y[idx]
        else:
            xs = x.view(-1, frames, dim)[idx]
            logits = model(xs).reshape(-1, 5)
            target = y.view(-1, frames)[idx].reshape(-1)
        loss = nn.functional.cross_entropy(logits, target)
        opt.zero_grad()
        loss.backward()
        opt.step()
    model.eval()
    vx, vy, _ = val
    with torch.no_grad():
        if args.head == "fc":
            for start in range(0, len(vy), max(args.batch, 1024)):
                nn.functional.cross_entropy(
                    model(vx[start : start + 1024]), vy[start : start + 1024]
                )
        else:
            xs = vx.view(-1, frames, dim)
            for start in range(0, xs.shape[0], args.batch):
                logits = model(xs[start : start + args.batch]).reshape(-1, 5)
                nn.functional.cross_entropy(
                    logits, vy.view(-1, frames)[start : start + args.batch].reshape(-1)
                )


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--head", choices=["fc", "lstm"], default="fc")
    p.add_argument("--sequences", type=int, default=400)
    p.add_argument("--val-sequences", type=int, default=80)
    p.add_argument("--frames", type=int, default=90)
    p.add_argument("--dim", type=int, default=1280)
    p.add_argument("--batch", type=int, default=256)
    p.add_argument("--epochs", type=int, default=5)
    p.add_argument("--threads", type=int, default=2)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    train = make_split(args.sequences, args.frames, args.dim, 1)
    val = make_split(args.val_sequences, args.frames, args.dim, 2)
    model = nn.Linear(args.dim, 5) if args.head == "fc" else LstmHead(args.dim)
    opt = torch.optim.Adam(model.parameters(), lr=5e-4, weight_decay=5e-4)
    g = torch.Generator().manual_seed(0)
    times = []
    for _ in range(args.epochs):
        t = time.perf_counter()
        epoch(args, model, opt, train, val, g)
        times.append(time.perf_counter() - t)
    rest = sorted(times[1:] if len(times) > 1 else times)
    print(
        json.dumps(
            {
                "impl": "pytorch " + torch.__version__,
                "head": args.head,
                "median_epoch_s": round(rest[len(rest) // 2], 4),
                "epochs_s": [round(t, 4) for t in times],
            }
        )
    )


if __name__ == "__main__":
    main()
