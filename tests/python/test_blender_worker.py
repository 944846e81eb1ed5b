"""The Blender side on its own: every texture family builds, the worker
renders a tiny Workbench sequence, and bad meshes are refused. With
GRASP_REQUIRE_BLENDER=1 (scripts/test.sh) a missing bpy fails instead of
skipping."""

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

if os.environ.get("GRASP_REQUIRE_BLENDER") == "1":
    import bpy
else:
    bpy = pytest.importorskip("bpy")

from blender_scripts import materials, render, world  # noqa: E402
from blender_scripts.worker import Worker  # noqa: E402

GEOMETRY = {
    "room": {"min_xy": [-2.0, -2.0], "max_xy": [2.0, 2.0], "height": 2.7},
    "table": {"min_xy": [-0.4, -0.4], "max_xy": [0.4, 0.4], "height": 0.75, "thickness": 0.04},
}
SETTINGS = {
    "engine": "workbench",
    "samples": 1,
    "passes": ["rgb"],
    "bounces": {"total": 1, "diffuse": 1, "glossy": 1, "transmission": 1, "transparent": 1},
}


def surface(family):
    return {
        "family": family,
        "color_a": [0.8, 0.2, 0.1],
        "color_b": [0.1, 0.2, 0.8],
        "scale": 3.0,
        "roughness": 0.5,
        "detail": 0.5,
    }


def cube_bytes():
    v = np.array([[x, y, z] for z in (0, 0.1) for y in (-0.05, 0.05) for x in (-0.05, 0.05)], "<f8")
    f = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                  [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]], "<u4")  # fmt: skip
    return v.tobytes(), f.tobytes()


def plan(frames=2):
    s = 0.5**0.5
    # The camera 0.6 m in front of the object (-Y), looking along +Y.
    pose = {"position": [0.0, -0.6, 0.85], "rotation_wxyz": [s, s, 0.0, 0.0]}
    appearance = {
        "wall": surface("brick"),
        "floor": surface("marble"),
        "table": surface(materials.HELD_OUT_FAMILY),
        "object": {"randomized": True, "color": [0.9, 0.1, 0.1], "roughness": 0.4},
        "lights": [{"kind": "area", "position": [0, -1, 2], "power_w": 200, "tint": [1, 1, 1]}],
        "exposure": 0.0,
        "hand_visible": True,
    }
    k = {"width": 32, "height": 24, "fx": 30.0, "fy": 30.0, "cx": 16.0, "cy": 12.0}
    k.update(clip_near=0.01, clip_far=20.0)
    return {
        "key": {"object": "cube"},
        "object": {"pose": {"position": [0, 0, 0.75], "rotation_wxyz": [1, 0, 0, 0]}},
        "intrinsics": k,
        "frames": [{"index": i, "camera": pose} for i in range(frames)],
        "appearance": appearance,
    }


@pytest.mark.parametrize("family", [f for f in materials.FAMILIES if f != "image"])
def test_every_family_builds(family):
    mat = bpy.data.materials.new(f"test_{family}")
    materials.apply_surface(mat, surface(family))
    assert len(mat.node_tree.nodes) > 3


def _rust_families(path, name):
    """The string array `pub const NAME: [&str; N] = [...]` of a Rust file."""
    src = (Path(__file__).resolve().parents[2] / path).read_text()
    block = re.search(rf"pub const {name}: \[&str; \d+\] = \[(.*?)\];", src, re.S)
    assert block, f"{name} not found in {path}"
    return re.findall(r'"([a-z_]+)"', block.group(1))


def test_families_match_the_generator():
    # The planner draws families by name; each must have a builder here.
    base = _rust_families("generator/src/appearance.rs", "BASE_FAMILIES")
    reserved = _rust_families("generator/src/look/unseen_config.rs", "UNSEEN_FAMILIES")
    assert set(base + reserved) == set(materials.FAMILIES)
    assert reserved == list(materials.UNSEEN_FAMILIES)


def test_unknown_family_is_refused():
    mat = bpy.data.materials.new("test_unknown")
    with pytest.raises(ValueError, match="unknown texture family 'plaid'"):
        materials.apply_surface(mat, surface("plaid"))


def test_worker_renders_a_sequence(tmp_path):
    worker = Worker(GEOMETRY, SETTINGS)
    worker.add_mesh("cube", *cube_bytes())
    assert worker.has_mesh("cube")
    names = ["00000.png", "00001.png"]
    worker.render(plan(), str(tmp_path), names, [0.5, 0.5, 0.5])
    for name in names:
        image = bpy.data.images.load(str(tmp_path / name))
        assert tuple(image.size) == (32, 24)
        pixels = np.array(image.pixels[:]).reshape(24, 32, 4)[:, :, :3]
        assert pixels.std() > 0.01, "a uniform frame"
    # Only the named frames are written.
    assert sorted(os.listdir(tmp_path)) == names
    json.dumps(plan())  # the plan stays plain JSON


def test_center_region_renders_only_the_central_square(tmp_path):
    settings = dict(SETTINGS, engine="cycles", samples=1, denoiser="none", center_region=0.5)
    worker = Worker(GEOMETRY, settings)
    worker.add_mesh("cube", *cube_bytes())
    worker.render(plan(frames=1), str(tmp_path), ["00000.png"], [0.5, 0.5, 0.5])
    image = bpy.data.images.load(str(tmp_path / "00000.png"))
    assert tuple(image.size) == (32, 24)
    # Rows bottom-up; the square is 0.5 x 24 = 12 px: columns 10-21, rows 6-17.
    rgb = np.array(image.pixels[:]).reshape(24, 32, 4)[:, :, :3]
    inside = rgb[7:17, 11:21]
    assert (inside.sum(axis=2) > 0).mean() > 0.9, "the central square is rendered"
    outside = np.ones((24, 32), bool)
    outside[5:19, 9:23] = False  # one pixel of slack around the square
    # Black, up to Blender's dither of one grey level.
    assert rgb[outside].max() <= 1.5 / 255, "everything else stays black"
    # Whole frames again for the next worker.
    Worker(GEOMETRY, SETTINGS)
    assert not bpy.context.scene.render.use_border


def test_cycles_reports_every_gpu_backend_and_switches_to_the_cpu():
    # The generator picks among these names (generator/src/render/device.rs).
    Worker(GEOMETRY, dict(SETTINGS, engine="cycles"))
    found = render.cycles_gpu_devices()
    assert sorted(found) == sorted(render.GPU_BACKENDS)
    assert all(isinstance(v, list) for v in found.values())
    src = (Path(__file__).resolve().parents[2] / "generator/src/render/device.rs").read_text()
    for backend in render.GPU_BACKENDS:
        assert f'"{backend}"' in src, backend
    render.use_device("cpu")
    assert bpy.context.scene.cycles.device == "CPU"


def test_bad_meshes_are_refused():
    worker = Worker(GEOMETRY, SETTINGS)
    v, _ = cube_bytes()
    with pytest.raises(ValueError, match="out of range"):
        worker.add_mesh("bad", v, np.array([[0, 1, 99]], "<u4").tobytes())
    with pytest.raises(ValueError, match="whole triangles"):
        worker.add_mesh("bad", v[:-8], np.array([[0, 1, 2]], "<u4").tobytes())


def test_depth_and_instance_passes_write_an_exr(tmp_path):
    settings = dict(SETTINGS, engine="cycles", samples=1, denoiser="none")
    settings["passes"] = ["rgb", "depth", "instance"]
    worker = Worker(GEOMETRY, settings)
    worker.add_mesh("cube", *cube_bytes())
    worker.render(plan(frames=1), str(tmp_path), ["00000.png"], [0.5, 0.5, 0.5])
    assert sorted(os.listdir(tmp_path)) == ["00000.exr", "00000.png"]
    header = (tmp_path / "00000.exr").read_bytes()[:4096]
    assert header[:4] == b"\x76\x2f\x31\x01"  # the OpenEXR magic number
    for channel in (b"ViewLayer.Depth.Z", b"ViewLayer.Object Index.X", b"ViewLayer.Combined.R"):
        assert channel in header, channel


# The bundled studio-light worlds the generator's config may name
# (generator/src/look/checks.rs, BUNDLED_HDRIS).
BUNDLED_HDRIS = ["city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"]


@pytest.mark.parametrize("name", BUNDLED_HDRIS)
def test_the_wheel_ships_the_studio_light_worlds(name):
    assert os.path.getsize(world.hdri_path(name)) > 10_000


def test_an_unknown_world_is_refused():
    with pytest.raises(ValueError, match="world HDRI 'beach' not found"):
        world.hdri_path("beach")


def test_worker_applies_unseen_lights_world_tone_and_distractors(tmp_path):
    settings = dict(SETTINGS, view_transform="AgX")
    worker = Worker(GEOMETRY, settings)
    worker.add_mesh("cube", *cube_bytes())
    p = plan()
    light = {"position": [0.5, 0.5, 1.5], "power_w": 20.0, "color_temperature_k": 9000.0}
    light["tint"] = [0.8, 0.9, 1.0]
    p["appearance"]["lights"] = [dict(light, kind="sun")] + [dict(light, kind="ring")] * 5
    p["appearance"]["world"] = {"hdri": "courtyard", "rotation_deg": 30.0, "strength": 0.5}
    p["appearance"]["tone"] = {"view_transform": "Khronos PBR Neutral", "look": "None"}
    p["appearance"]["motion_blur"] = {"shutter": 0.5}
    box = {"shape": "box", "size": [0.05, 0.05, 0.1], "color": [0.2, 0.6, 0.2], "roughness": 0.5}
    p["distractors"] = [
        dict(box, pose={"position": [0.2, 0.1, 0.8], "rotation_wxyz": [1, 0, 0, 0]}),
        dict(
            box, shape="sphere", pose={"position": [-0.2, 0.1, 0.8], "rotation_wxyz": [1, 0, 0, 0]}
        ),
    ]
    worker.render(p, str(tmp_path), ["00000.png", "00001.png"], [0.5, 0.5, 0.5])
    scene = bpy.context.scene
    assert scene.view_settings.view_transform == "Khronos PBR Neutral"
    assert scene.world.name == "world_hdri"
    # Nothing of a worker's earlier sequences carries over (determinism).
    assert not scene.render.use_persistent_data
    # A small importance map: the automatic one (the HDRI's own 1K) doubled
    # the render time of a frame at 1 sample (docs/rendering.md).
    assert scene.world.cycles.sampling_method == "MANUAL"
    assert scene.world.cycles.sample_map_resolution == 256
    assert bpy.data.objects["ceiling"].hide_render, "the room opens to the sky"
    assert not bpy.data.objects["sun0"].hide_render
    assert sum(not bpy.data.objects[f"ring{i}"].hide_render for i in range(8)) == 5
    shown = [o for o in bpy.data.objects if o.name.startswith("distractor") and not o.hide_render]
    assert len(shown) == 2 and all(o.pass_index == 0 for o in shown)
    assert bpy.data.objects["distractor1"].data.name == "distractor_sphere"
    # Workbench renders no motion blur.
    assert not scene.render.use_motion_blur
    # The next plan without them restores the closed room and the defaults.
    worker.render(plan(), str(tmp_path), ["00000.png", "00001.png"], [0.5, 0.5, 0.5])
    assert scene.view_settings.view_transform == "AgX"
    assert scene.world.name == "world"
    assert not bpy.data.objects["ceiling"].hide_render
    assert all(o.hide_render for o in bpy.data.objects if o.name.startswith("distractor"))
