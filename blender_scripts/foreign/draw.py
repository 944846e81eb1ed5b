"""What the foreign world draws per sequence: plain values, no bpy.

The draws come from Python's own generator seeded with a string of the
plan's `stream_seed`, so they depend
on the sequence and on nothing else, and no random stream of the planner
sees them: plans and labels are the same in every world. They are a pure
function of the plan, so a sequence re-renders to the same values.

The ranges are chosen apart from training's (`configs/default.toml`
[appearance], [randomize.*]) and from the held-out looks' where an axis can
be told apart: the light colour temperature, the view transform and look,
the lens model (distortion, vignetting, rolling shutter) and the exposure
rule have no overlap with any of them.
"""

import colorsys
import random

# Changing what is drawn changes this tag, so old and new draws differ
# everywhere instead of shifting silently.
SEED_TAG = "grasp-gen foreign world 1"

TABLE_KINDS = ("wood", "laminate", "stone", "cloth")
FLOOR_KINDS = ("parquet", "tiles", "concrete")
# The window's wall, seen from the user: ahead (+X), left (+Y) or right (-Y).
WINDOW_WALLS = ("ahead", "left", "right")
# Sky models of Blender's Sky Texture node (training has no sky texture).
SKY_TYPES = ("HOSEK_WILKIE", "PREETHAM")
# Tone curves no training set or held-out look uses (training: AgX; looks:
# Khronos PBR Neutral, Filmic, Standard).
VIEW_TRANSFORMS = ("ACES 2.0", "ACES 1.3")
# ACES looks, named without their transform's prefix.
LOOKS = ("None", "Reference Gamut Compression")
# Warm lamps below training's 2700-6500 K.
LAMP_TEMPERATURE_K = (2200.0, 2600.0)
HAND_SHELLS = ((0.62, 0.63, 0.65), (0.85, 0.84, 0.8), (0.2, 0.21, 0.23))


def seed_string(plan):
    # The "/None" suffix keeps the draws of the renders made so far.
    return f"{SEED_TAG}/{plan['stream_seed']}/None"


def _hsv(h, s, v):
    return list(colorsys.hsv_to_rgb(h % 1.0, s, v))


def _srgb_to_linear(c):
    return [x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4 for x in c]


def _object_finish(r, color, color_range):
    """The object's colour (linear RGB): drawn from the real object's
    plausible HSV range where the catalog gives one, else its own colour
    moved a little in HSV."""
    if color_range is not None:
        h = r.uniform(*color_range["hue"])
        s = r.uniform(*color_range["saturation"])
        v = r.uniform(*color_range["value"])
    else:
        srgb = [max(0.0, min(1.0, x)) ** (1 / 2.2) for x in color]
        h, s, v = colorsys.rgb_to_hsv(*srgb)
        h += r.uniform(-0.02, 0.02)
        s = min(1.0, s * r.uniform(0.85, 1.1))
        v = min(1.0, v * r.uniform(0.85, 1.1))
    return {
        "color": _srgb_to_linear(colorsys.hsv_to_rgb(h % 1.0, s, v)),
        "wear": r.uniform(0.0, 1.0),  # scuffs, speckles: per-finish detail
    }


def draw(plan, object_color, color_range=None):
    """The sequence's foreign-world values (a dict of plain values).
    `object_color`: the object's own linear RGB; `color_range`: the
    catalog's plausible HSV ranges ({hue, saturation, value}) or None."""
    r = random.Random(seed_string(plan))
    table_kind = r.choice(TABLE_KINDS)
    wood_tone = r.uniform(0.04, 0.11)
    table = {
        "kind": table_kind,
        # Wood and laminate: a brown; stone: a grey or beige; cloth: a dyed
        # linen. Values are sRGB-ish HSV, turned linear by the material.
        "hsv": {
            "wood": (wood_tone, r.uniform(0.35, 0.65), r.uniform(0.25, 0.65)),
            "laminate": (r.uniform(0.05, 0.12), r.uniform(0.1, 0.45), r.uniform(0.55, 0.9)),
            "stone": (r.uniform(0.05, 0.6), r.uniform(0.0, 0.12), r.uniform(0.35, 0.85)),
            "cloth": (r.uniform(0.0, 1.0), r.uniform(0.2, 0.6), r.uniform(0.3, 0.8)),
        }[table_kind],
        "grain_scale": r.uniform(0.6, 1.6),
        "grain_angle": r.uniform(-0.15, 0.15),
        "roughness": r.uniform(0.25, 0.6),
    }
    floor = {
        "kind": r.choice(FLOOR_KINDS),
        "hsv": (r.uniform(0.04, 0.12), r.uniform(0.15, 0.6), r.uniform(0.2, 0.65)),
    }
    wall_hsv = (r.uniform(0.0, 1.0), r.uniform(0.02, 0.18), r.uniform(0.6, 0.92))
    window = r.choice(WINDOW_WALLS)
    sun_elevation = r.uniform(8.0, 55.0)
    sky = {
        "type": r.choice(SKY_TYPES),
        "turbidity": r.uniform(2.0, 5.0),
        "sun_elevation_deg": sun_elevation,
        # The sun stands outside the window's wall, up to 50 deg off its normal.
        "sun_off_normal_deg": r.uniform(-50.0, 50.0),
        "strength": r.uniform(15.0, 40.0),
        "sun_strength": r.uniform(20.0, 50.0),
    }
    lamp = {
        "on": r.random() < 0.5,
        "temperature_k": r.uniform(*LAMP_TEMPERATURE_K),
        "power_w": r.uniform(15.0, 45.0),
        "drop_m": r.uniform(0.6, 1.0),  # pendant below the ceiling
        "offset": [r.uniform(-0.4, 0.4), r.uniform(-0.5, 0.5)],
    }
    camera = {
        "distortion": r.uniform(0.025, 0.06),  # barrel (Blender: positive)
        "dispersion": r.uniform(0.001, 0.004),  # lateral chromatic aberration
        "vignette": r.uniform(0.25, 0.5),  # corner fall-off
        "view_transform": r.choice(VIEW_TRANSFORMS),
        "look": r.choice(LOOKS),
        # Auto exposure: stops around the metered value (camera.py).
        "exposure_bias": r.uniform(-0.5, 0.3),
        "readout_s": r.uniform(0.012, 0.03),  # rolling shutter, top to bottom
        "bloom": r.uniform(0.05, 0.2),
    }
    clutter = {
        "counter_srgb": _hsv(r.uniform(0.0, 1.0), r.uniform(0.05, 0.4), r.uniform(0.3, 0.85)),
        "books_srgb": [
            _hsv(r.uniform(0.0, 1.0), r.uniform(0.3, 0.8), r.uniform(0.2, 0.7)) for _ in range(7)
        ],
        "chair": r.random() < 0.6,
        "mug_on_counter": r.random() < 0.5,
    }
    return {
        "seed": seed_string(plan),
        "table": table,
        "floor": floor,
        "wall_hsv": wall_hsv,
        "window": window,
        "sky": sky,
        "lamp": lamp,
        "camera": camera,
        "clutter": clutter,
        "object": _object_finish(r, object_color, color_range),
        "hand": {"visible": r.random() < 0.8, "shell": list(r.choice(HAND_SHELLS))},
    }
