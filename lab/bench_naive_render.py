"""The naive peer of `grasp-gen render`, for BENCHMARKS.md: for every
sequence it rebuilds the whole Blender scene from factory settings and
renders frame by frame (one render call and one PNG write per frame).

It re-renders the sequences of a dataset made by `grasp-gen render` (same
plans, same meshes, same engine settings from each sequence.json), so the
frames and settings match the measured run exactly.

    .venv/bin/python lab/bench_naive_render.py DATASET OUT
"""

import json
import os
import sys
import time

from blender_scripts.worker import Worker


def sequences(root):
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        if "sequence.json" in filenames:
            yield os.path.relpath(dirpath, root)


def main(root, out):
    work = os.path.join(root, ".grasp-gen")
    with open(os.path.join(work, "scene.json")) as f:
        geometry = json.load(f)
    frames = 0
    start = time.perf_counter()
    for rel in sorted(sequences(root)):
        with open(os.path.join(root, rel, "sequence.json")) as f:
            record = json.load(f)
        settings = dict(record["render"], one_call=False)
        plan = record["plan"]
        obj = plan["key"]["object"]
        worker = Worker(geometry, settings)  # the whole scene, every sequence
        with open(os.path.join(work, "meshes", f"{obj}.vertices.f64"), "rb") as f:
            vertices = f.read()
        with open(os.path.join(work, "meshes", f"{obj}.faces.u32"), "rb") as f:
            faces = f.read()
        worker.add_mesh(obj, vertices, faces)
        target = os.path.join(out, rel)
        os.makedirs(target, exist_ok=True)
        worker.render(plan, target, record["frame_files"], plan["appearance"]["object"]["color"])
        frames += len(record["frame_files"])
    seconds = time.perf_counter() - start
    print(f"naive: {frames} frames in {seconds:.1f} s = {frames / seconds:.3f} frames/s")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
