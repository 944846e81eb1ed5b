"""How a video's frames could vote (issue 41): per-video accuracy of the
main job's heads under other vote rules and ensembles, from the per-frame
probabilities that `trainer/examples/dump_predictions.rs` writes.

    lab/vote-rules.sh MAIN_OUT          # dumps, then runs this

    python lab/vote_rules.py DUMPS      # DUMPS/MODEL-SEED-SET.jsonl

Every table has one column per test set and the worst set last, pooled over
the seeds (62 videos x 3 seeds per set). `majority` is the rule that
`grasp-train eval` scores (ties to the larger probability mass), so its row
repeats the main job's report.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np

PRESHAPES = ["power", "lateral", "pinch", "pinch3"]
P = len(PRESHAPES)
FIVE = ["default", "fast", "from_ground", "seated", "background"]


def load(path):
    return [json.loads(line) for line in open(path)]


def truth(video):
    return PRESHAPES.index(video["preshape"])


def majority(probs):
    """The report's rule: frames predicting no_grasp do not vote."""
    frame = probs.argmax(1)
    votes = np.bincount(frame[frame < P], minlength=P)[:P]
    mass = probs[:, :P].sum(0)
    tied = [k for k in range(P) if votes[k] == votes.max()]
    return max(tied, key=lambda k: (mass[k], -k))


def soft(probs):
    """The mean probability of each pre-shape over the video."""
    return int(probs[:, :P].sum(0).argmax())


def product(probs):
    """Frames as independent evidence: summed log-probabilities."""
    return int(np.log(np.clip(probs[:, :P], 1e-6, 1.0)).sum(0).argmax())


def certainty(probs):
    """Majority with each frame weighed by 1 - its normalised entropy."""
    q = probs[:, :P] / probs[:, :P].sum(1, keepdims=True)
    entropy = -(q * np.log(np.clip(q, 1e-9, 1.0))).sum(1) / math.log(P)
    score = np.zeros(P)
    np.add.at(score, q.argmax(1), 1.0 - entropy)
    return int(score.argmax())


def first(fraction):
    """Majority of the frames before a fraction of the video."""

    def rule(probs):
        return majority(probs[: max(1, math.ceil(len(probs) * fraction))])

    return rule


RULES = {
    "majority": majority,
    "soft": soft,
    "product": product,
    "certainty": certainty,
    "first 60 %": first(0.6),
    "first 80 %": first(0.8),
}


def runs(dumps, model):
    """{set: [videos of seed 0, videos of seed 1, ...]}."""
    sets = {}
    for path in sorted(Path(dumps).glob(f"{model}-*-*.jsonl")):
        seed, name = path.stem[len(model) + 1 :].split("-", 1)
        sets.setdefault(name, {})[int(seed)] = load(path)
    return {k: [v[s] for s in sorted(v)] for k, v in sets.items()}


def accuracy(seeds, rule, combine=None):
    """Per-video accuracy (%) pooled over seeds; `combine` merges the
    aligned videos of several runs into one probability array."""
    ok = total = 0
    for videos in seeds:
        for video in videos:
            probs = combine(video) if combine else np.array(video["probs"])
            if len(probs) == 0:
                continue
            ok += rule(probs) == truth(video[0] if combine else video)
            total += 1
    return 100.0 * ok / total


def table(title, rows, sets):
    print(f"\n{title}\n")
    print("| rule | " + " | ".join(sets) + " | mean of five | worst |")
    print("|---" * (len(sets) + 3) + "|")
    for name, accs in rows:
        five = [accs[sets.index(s)] for s in FIVE if s in sets]
        five = f"{np.mean(five):.1f}" if five else "–"
        cells = " | ".join(f"{a:.1f}" for a in accs)
        print(f"| {name} | {cells} | {five} | {min(accs):.1f} |")


def mean_probs(videos, weights):
    assert len({v["id"] for v in videos}) == 1, "runs do not align"
    return sum(w * np.array(v["probs"]) for v, w in zip(videos, weights))


def main(dumps):
    fc, lstm = runs(dumps, "fc"), runs(dumps, "lstm")
    sets = sorted(fc)
    for model, data in [("FC recipe", fc), ("LSTM", lstm)]:
        if data:
            rows = [(n, [accuracy(data[s], r) for s in sets]) for n, r in RULES.items()]
            table(f"{model}: vote rules", rows, sets)
    # The three FC seeds averaged: is the error variance or bias?
    seeds3 = {s: [list(zip(*fc[s]))] for s in sets}
    rows = [
        (n, [accuracy(seeds3[s], RULES[n], lambda v: mean_probs(v, [1 / 3] * 3)) for s in sets])
        for n in ["majority", "soft"]
    ]
    table("FC recipe, its three seeds averaged frame by frame", rows, sets)
    if lstm:
        pairs = {s: [list(zip(a, b)) for a, b in zip(fc[s], lstm[s])] for s in sets}
        # An LSTM read at its training rate steps less often than the FC
        # head votes (docs/trainer.md, "Heads"): frame by frame, the two
        # then do not align, and only their mean probabilities mix.
        aligned = all(
            len(a["probs"]) == len(b["probs"]) for s in sets for run in pairs[s] for a, b in run
        )
        rules = ["majority", "soft"] if aligned else ["soft"]
        rows = []
        for w in [0.7, 0.5, 0.3]:
            for n in rules:

                def combine(v, w=w, frames=n != "soft"):
                    if frames:
                        return mean_probs(v, [w, 1 - w])
                    return mean_probs([mean_frame(x) for x in v], [w, 1 - w])

                rows.append(
                    (
                        f"{w:.1f} FC + {1 - w:.1f} LSTM, {n}",
                        [accuracy(pairs[s], RULES[n], combine) for s in sets],
                    )
                )
        table("FC recipe and LSTM of the same seed, probabilities mixed", rows, sets)


def mean_frame(video):
    """The video as one frame: its frames' mean probabilities."""
    probs = np.array(video["probs"])
    return {**video, "probs": probs.mean(0, keepdims=True) if len(probs) else probs}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "runs/main/lab/predictions")
