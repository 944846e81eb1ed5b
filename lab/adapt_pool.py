"""Pool the cross-fitted adaptation reports of lab/adapt-variant.sh.

    python3 lab/adapt_pool.py REPORTS_DIR

REPORTS_DIR/NAME/SET/on-H/report.json for NAME in (base, adapted): every
video scored by a model that was never adapted on it (adapted on the other
draw). Prints, per set, the hand's decision and the per-video vote of each,
mean over seeds of the pooled videos, as a Markdown table.
"""

import json
import sys
from pathlib import Path


def pooled(set_dir: Path) -> tuple[float, float, int]:
    by_seed: dict[int, list[tuple[bool, bool]]] = {}
    for half in sorted(set_dir.glob("on-*")):
        report = json.loads((half / "report.json").read_text())
        for k, run in enumerate(report["runs"]):
            for v in run["videos"]:
                hand = (v.get("hand") or {}).get("preshape") == v["truth"]
                by_seed.setdefault(k, []).append((hand, v["vote"] == v["truth"]))
    hands = [sum(h for h, _ in vs) / len(vs) for vs in by_seed.values()]
    votes = [sum(v for _, v in vs) / len(vs) for vs in by_seed.values()]
    videos = len(next(iter(by_seed.values())))
    return 100 * sum(hands) / len(hands), 100 * sum(votes) / len(votes), videos


def main() -> None:
    root = Path(sys.argv[1])
    sets = sorted(p.name for p in (root / "base").iterdir() if p.is_dir())
    print("| set | videos | hand, as shipped | hand, adapted | vote, as shipped | vote, adapted |")
    print("|---|---|---|---|---|---|")
    worst = {"base": [101.0, 101.0], "adapted": [101.0, 101.0]}
    for s in sets:
        b = pooled(root / "base" / s)
        a = pooled(root / "adapted" / s)
        for name, r in (("base", b), ("adapted", a)):
            worst[name] = [min(worst[name][0], r[0]), min(worst[name][1], r[1])]
        print(f"| {s} | {b[2]} | {b[0]:.1f} | {a[0]:.1f} | {b[1]:.1f} | {a[1]:.1f} |")
    wb, wa = worst["base"], worst["adapted"]
    print(f"| **worst** | | {wb[0]:.1f} | {wa[0]:.1f} | {wb[1]:.1f} | {wa[1]:.1f} |")


if __name__ == "__main__":
    main()
