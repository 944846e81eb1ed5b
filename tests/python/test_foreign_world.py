"""The foreign world's Python side: its per-sequence draws (no bpy needed)
are a pure function of the plan's stream seed, never of training's
appearance, and stay apart from training's values where the docs say so;
with bpy, every material builds and the worker renders a lit sequence.
With GRASP_REQUIRE_BLENDER=1 (scripts/test.sh) a missing bpy fails the
Blender tests instead of skipping them."""

import copy
import os

import numpy as np
import pytest

from blender_scripts.foreign import draw

RANGE = {"hue": [-0.03, 0.03], "saturation": [0.6, 0.9], "value": [0.5, 0.85]}


def plan(stream_seed=11, frames=2):
    pose = {"position": [-0.45, 0.0, 0.95], "rotation_wxyz": [0.5, 0.5, -0.5, -0.5]}
    k = {"width": 32, "height": 24, "fx": 30.0, "fy": 30.0, "cx": 16.0, "cy": 12.0}
    k.update(clip_near=0.01, clip_far=20.0)
    return {
        "stream_seed": stream_seed,
        "fps": 2.5,
        "key": {"object": "025_mug"},
        "object": {"pose": {"position": [0, 0, 0.75], "rotation_wxyz": [1, 0, 0, 0]}},
        "intrinsics": k,
        "frames": [{"index": i, "camera": pose} for i in range(frames)],
        "appearance": {"exposure": 0.3, "hand_visible": True},
    }


def test_draws_follow_the_stream_seed_and_nothing_of_trainings_appearance():
    a = draw.draw(plan(11), [0.5, 0.2, 0.1], RANGE)
    assert a == draw.draw(plan(11), [0.5, 0.2, 0.1], RANGE)
    assert a != draw.draw(plan(12), [0.5, 0.2, 0.1], RANGE)
    other = plan(11)
    other["appearance"] = {"exposure": -0.4, "hand_visible": False}
    assert draw.draw(other, [0.5, 0.2, 0.1], RANGE) == a


def test_draws_stay_apart_from_trainings_values():
    training_tones = {"AgX", "Standard", "Filmic", "Khronos PBR Neutral"}
    for seed in range(200):
        d = draw.draw(plan(seed), [0.5, 0.2, 0.1], RANGE)
        lamp = d["lamp"]["temperature_k"]
        assert lamp < 2700.0, "training's lamps: 2700-6500 K"
        assert d["camera"]["view_transform"] not in training_tones
        assert d["table"]["kind"] in draw.TABLE_KINDS
        # The object's colour comes from the catalog's plausible range: red.
        r, g, b = d["object"]["color"]
        assert r > 2 * g and r > 2 * b, d["object"]["color"]


def test_without_a_colour_range_the_objects_own_colour_is_kept_close():
    d = draw.draw(plan(3), [0.1, 0.6, 0.1], None)
    r, g, b = d["object"]["color"]
    assert g > 2 * r and g > 2 * b


@pytest.fixture(scope="module")
def bpy():
    if os.environ.get("GRASP_REQUIRE_BLENDER") == "1":
        import bpy as module
    else:
        module = pytest.importorskip("bpy")
    return module


GEOMETRY = {
    "room": {"min_xy": [-3.0, -3.0], "max_xy": [3.0, 3.0], "height": 3.0},
    "table": {"min_xy": [-0.4, -0.7], "max_xy": [0.4, 0.7], "height": 0.75, "thickness": 0.04},
}
SETTINGS = {"engine": "cycles", "samples": 1, "passes": ["rgb"], "denoiser": "none"}


def cube_bytes():
    v = np.array([[x, y, z] for z in (0, 0.1) for y in (-0.05, 0.05) for x in (-0.05, 0.05)], "<f8")
    f = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                  [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]], "<u4")  # fmt: skip
    return v.tobytes(), f.tobytes()


def test_every_material_builds(bpy):
    from blender_scripts.foreign import materials

    for kind in draw.TABLE_KINDS:
        mat = bpy.data.materials.new(f"t_{kind}")
        spec = {"kind": kind, "hsv": (0.1, 0.4, 0.6), "grain_scale": 1.0, "grain_angle": 0.0}
        materials.table_material(mat, dict(spec, roughness=0.4))
        assert len(mat.node_tree.nodes) > 3
    for kind in draw.FLOOR_KINDS:
        materials.floor_material(
            bpy.data.materials.new(f"f_{kind}"), {"kind": kind, "hsv": (0.1, 0.4, 0.5)}
        )
    for finish in sorted(set(materials.FINISHES.values())):
        mat = bpy.data.materials.new(f"o_{finish}")
        materials.object_finish(mat, finish, (0.5, 0.1, 0.1), 0.5)
    with pytest.raises(ValueError, match="unknown finish 'velvet'"):
        materials.object_finish(mat, "velvet", (0.5, 0.1, 0.1), 0.5)
    assert materials.finish_of("some_ycb_object") == "plastic"


def test_worker_renders_a_lit_sequence_and_refuses_what_it_cannot_draw(bpy, tmp_path):
    from blender_scripts.foreign.worker import Worker

    worker = Worker(GEOMETRY, SETTINGS)
    worker.add_mesh("025_mug", *cube_bytes())
    names = ["00000.png", "00001.png"]
    p = plan(5)
    worker.render(copy.deepcopy(p), str(tmp_path), names, [0.5, 0.5, 0.5], color_range=RANGE)
    assert sorted(os.listdir(tmp_path)) == names
    for name in names:
        image = bpy.data.images.load(str(tmp_path / name))
        assert tuple(image.size) == (32, 24)
        pixels = np.array(image.pixels[:]).reshape(24, 32, 4)[:, :, :3]
        assert pixels.std() > 0.01, "a uniform frame"
        assert 0.05 < pixels.mean() < 0.95, f"black or blown out: {pixels.mean()}"
    assert bpy.context.scene.view_settings.view_transform.startswith("ACES")
    assert bpy.context.scene.cycles.use_guiding
    with pytest.raises(ValueError, match="wrist camera only"):
        worker.render_camera(p, "head", str(tmp_path), names)
    with pytest.raises(ValueError, match="Cycles only"):
        Worker(GEOMETRY, dict(SETTINGS, engine="workbench"))
    with pytest.raises(ValueError, match="rgb only"):
        Worker(GEOMETRY, dict(SETTINGS, passes=["rgb", "depth"]))
