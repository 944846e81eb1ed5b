"""Split a generated test set into its two draws per object-part pair.

    python3 lab/adapt_halves.py TEST_SET OUT

Writes OUT/half-0 and OUT/half-1: each a dataset root with the manifest
lines of one draw (the id's last field, 00000 or 00001) and links to
their sequence folders, so that adaptation and scoring read apart draws.
"""

import json
import os
import sys
from pathlib import Path


def main() -> None:
    src, out = Path(sys.argv[1]).resolve(), Path(sys.argv[2])
    lines = (src / "manifest.jsonl").read_text().splitlines()
    halves: dict[int, list[str]] = {0: [], 1: []}
    for line in lines:
        entry = json.loads(line)
        draw = int(entry["id"].rsplit("/", 1)[1]) % 2
        halves[draw].append(line)
        link = out / f"half-{draw}" / entry["path"]
        link.parent.mkdir(parents=True, exist_ok=True)
        if not link.exists():
            os.symlink(src / entry["path"], link)
    for draw, kept in halves.items():
        (out / f"half-{draw}" / "manifest.jsonl").write_text("\n".join(kept) + "\n")


if __name__ == "__main__":
    main()
