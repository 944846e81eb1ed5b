"""The foreign world's node set: Principled BSDF materials with their own
procedural patterns (wood grain, laminate, polished stone, woven cloth,
plaster, parquet, tiles, concrete, brushed metal) and object finishes by
material (ceramic glaze, plastic, tinplate, waxy fruit skin, paper, leather,
painted wood). Textures read object coordinates in metres, so a pattern's
size does not depend on a mesh's UVs (the objects have none).

Colours come in as sRGB (or HSV of sRGB) and are made linear here."""

import colorsys

import bpy


def linear(srgb):
    return tuple(x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4 for x in srgb)


def hsv_linear(hsv):
    return linear(colorsys.hsv_to_rgb(hsv[0] % 1.0, hsv[1], hsv[2]))


def scaled(rgb, k):
    return tuple(max(0.0, min(1.0, x * k)) for x in rgb)


class Graph:
    """A material's node tree, cleared, with a Principled BSDF wired to
    the output."""

    def __init__(self, mat):
        mat.use_nodes = True
        self.tree = mat.node_tree
        self.tree.nodes.clear()
        self.out = self.node("ShaderNodeOutputMaterial")
        self.bsdf = self.node("ShaderNodeBsdfPrincipled")
        self.link(self.bsdf.outputs["BSDF"], self.out.inputs["Surface"])
        self._coords = None

    def node(self, kind, **props):
        n = self.tree.nodes.new(kind)
        for k, v in props.items():
            setattr(n, k, v)
        return n

    def link(self, a, b):
        self.tree.links.new(a, b)

    def coords(self, scale=(1.0, 1.0, 1.0), rotation_z=0.0):
        """Object coordinates (metres), scaled per axis and turned about Z."""
        if self._coords is None:
            self._coords = self.node("ShaderNodeTexCoord")
        m = self.node("ShaderNodeMapping")
        m.inputs["Scale"].default_value = scale
        m.inputs["Rotation"].default_value = (0.0, 0.0, rotation_z)
        self.link(self._coords.outputs["Object"], m.inputs["Vector"])
        return m.outputs["Vector"]

    def noise(self, vector, scale, detail=4.0, roughness=0.5, distortion=0.0):
        n = self.node("ShaderNodeTexNoise")
        n.inputs["Scale"].default_value = scale
        n.inputs["Detail"].default_value = detail
        n.inputs["Roughness"].default_value = roughness
        n.inputs["Distortion"].default_value = distortion
        self.link(vector, n.inputs["Vector"])
        return n

    def ramp(self, factor, stops):
        """A colour ramp over `stops`: [(position, rgb), ...]."""
        r = self.node("ShaderNodeValToRGB")
        elements = r.color_ramp.elements
        while len(elements) < len(stops):
            elements.new(0.5)
        for e, (pos, rgb) in zip(elements, stops):
            e.position = pos
            e.color = (*rgb, 1.0)
        self.link(factor, r.inputs["Fac"])
        return r.outputs["Color"]

    def bump(self, height, strength, distance=0.002):
        b = self.node("ShaderNodeBump")
        b.inputs["Strength"].default_value = strength
        b.inputs["Distance"].default_value = distance
        self.link(height, b.inputs["Height"])
        self.link(b.outputs["Normal"], self.bsdf.inputs["Normal"])
        return b

    def math(self, op, a, b=None):
        m = self.node("ShaderNodeMath", operation=op)
        for socket, value in zip(m.inputs, (a, b)):
            if value is None:
                continue
            if isinstance(value, bpy.types.NodeSocket):
                self.link(value, socket)
            else:
                socket.default_value = value
        return m.outputs["Value"]


def _color(g, name, rgb):
    g.bsdf.inputs[name].default_value = (*rgb, 1.0)


def _value(g, name, v):
    g.bsdf.inputs[name].default_value = v


def wood(mat, hsv, grain_scale=1.0, angle=0.0, roughness=0.4, varnish=0.8):
    """Wood: growth rings of a wave texture bent by noise, along X."""
    g = Graph(mat)
    v = g.coords((1.2 * grain_scale, 9.0 * grain_scale, 9.0 * grain_scale), angle)
    warp = g.noise(v, 1.5, detail=3.0)
    w = g.node("ShaderNodeTexWave", wave_type="RINGS", rings_direction="X")
    w.inputs["Scale"].default_value = 2.2
    w.inputs["Distortion"].default_value = 7.0
    w.inputs["Detail"].default_value = 3.0
    w.inputs["Detail Scale"].default_value = 1.5
    g.link(warp.outputs["Color"], w.inputs["Vector"])
    base = hsv_linear(hsv)
    dark = hsv_linear((hsv[0], min(1.0, hsv[1] * 1.15), hsv[2] * 0.55))
    fine = g.noise(g.coords((2.0, 160.0, 160.0), angle), 1.0, detail=2.0)
    grain = g.math("MULTIPLY", w.outputs["Fac"], fine.outputs["Fac"])
    g.link(g.ramp(grain, [(0.05, base), (0.6, dark)]), g.bsdf.inputs["Base Color"])
    _value(g, "Roughness", roughness)
    _value(g, "Coat Weight", varnish)
    _value(g, "Coat Roughness", 0.08)
    g.bump(grain, 0.08)


def laminate(mat, hsv, grain_scale=1.0, angle=0.0):
    """Laminate: a faint printed grain under a hard, even gloss; no relief."""
    g = Graph(mat)
    v = g.coords((1.0 * grain_scale, 25.0 * grain_scale, 25.0 * grain_scale), angle)
    n = g.noise(v, 2.0, detail=6.0, distortion=1.5)
    base = hsv_linear(hsv)
    g.link(g.ramp(n.outputs["Fac"], [(0.35, base), (0.7, scaled(base, 0.82))]),
           g.bsdf.inputs["Base Color"])  # fmt: skip
    _value(g, "Roughness", 0.32)
    _value(g, "Specular IOR Level", 0.6)


def stone(mat, hsv, roughness=0.25):
    """Polished stone: voronoi grains with thin noise veins."""
    g = Graph(mat)
    v = g.coords()
    vor = g.node("ShaderNodeTexVoronoi", feature="F1")
    vor.inputs["Scale"].default_value = 90.0
    vor.inputs["Randomness"].default_value = 1.0
    g.link(v, vor.inputs["Vector"])
    veins = g.noise(v, 6.0, detail=8.0, roughness=0.6, distortion=2.0)
    vein = g.ramp(veins.outputs["Fac"], [(0.48, (1, 1, 1)), (0.5, (0, 0, 0)), (0.52, (1, 1, 1))])
    base = hsv_linear(hsv)
    grains = g.ramp(vor.outputs["Distance"], [(0.0, scaled(base, 0.85)), (0.6, scaled(base, 1.1))])
    mix = g.node("ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
    mix.inputs["Factor"].default_value = 0.7
    g.link(grains, mix.inputs[6])
    g.link(vein, mix.inputs[7])
    g.link(mix.outputs[2], g.bsdf.inputs["Base Color"])
    _value(g, "Roughness", roughness)
    _value(g, "Coat Weight", 0.3)


def cloth(mat, hsv):
    """A woven tablecloth: warp and weft bands as relief, sheen, a little
    dye unevenness."""
    g = Graph(mat)
    v = g.coords()
    threads = []
    for direction in ("X", "Y"):
        w = g.node("ShaderNodeTexWave", wave_type="BANDS", bands_direction=direction)
        w.inputs["Scale"].default_value = 300.0
        w.inputs["Distortion"].default_value = 0.5
        g.link(v, w.inputs["Vector"])
        threads.append(w.outputs["Fac"])
    weave = g.math("MULTIPLY", threads[0], threads[1])
    dye = g.noise(v, 12.0, detail=3.0)
    base = hsv_linear(hsv)
    g.link(g.ramp(dye.outputs["Fac"], [(0.3, scaled(base, 0.85)), (0.7, base)]),
           g.bsdf.inputs["Base Color"])  # fmt: skip
    _value(g, "Roughness", 0.9)
    _value(g, "Sheen Weight", 0.7)
    _value(g, "Sheen Roughness", 0.4)
    g.bump(weave, 0.35, distance=0.001)


def plaster(mat, hsv):
    """Painted plaster: a flat paint over a soft trowelled relief."""
    g = Graph(mat)
    n = g.noise(g.coords(), 18.0, detail=6.0, roughness=0.65)
    _color(g, "Base Color", hsv_linear(hsv))
    _value(g, "Roughness", 0.8)
    g.bump(n.outputs["Fac"], 0.06)


def parquet(mat, hsv):
    """Oak parquet: long brick-laid planks, each its own shade, with grain."""
    g = Graph(mat)
    v = g.coords()
    b = g.node("ShaderNodeTexBrick", offset=0.5, offset_frequency=1, squash=1.0)
    b.inputs["Scale"].default_value = 1.0
    b.inputs["Brick Width"].default_value = 0.9
    b.inputs["Row Height"].default_value = 0.13
    b.inputs["Mortar Size"].default_value = 0.002
    base = hsv_linear(hsv)
    b.inputs["Color1"].default_value = (*base, 1)
    b.inputs["Color2"].default_value = (*scaled(base, 0.75), 1)
    b.inputs["Mortar"].default_value = (*scaled(base, 0.3), 1)
    g.link(v, b.inputs["Vector"])
    grain = g.noise(g.coords((3.0, 60.0, 60.0)), 1.0, detail=3.0)
    mix = g.node("ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
    mix.inputs["Factor"].default_value = 0.35
    g.link(b.outputs["Color"], mix.inputs[6])
    g.link(grain.outputs["Color"], mix.inputs[7])
    g.link(mix.outputs[2], g.bsdf.inputs["Base Color"])
    _value(g, "Roughness", 0.45)
    g.bump(b.outputs["Fac"], 0.3)


def tiles(mat, hsv):
    """Square glazed floor tiles with light grout."""
    g = Graph(mat)
    b = g.node("ShaderNodeTexBrick", offset=0.0, offset_frequency=1, squash=1.0)
    b.inputs["Scale"].default_value = 1.0
    b.inputs["Brick Width"].default_value = 0.3
    b.inputs["Row Height"].default_value = 0.3
    b.inputs["Mortar Size"].default_value = 0.004
    base = hsv_linear((hsv[0], hsv[1] * 0.5, min(1.0, hsv[2] * 1.2)))
    b.inputs["Color1"].default_value = (*base, 1)
    b.inputs["Color2"].default_value = (*scaled(base, 0.92), 1)
    b.inputs["Mortar"].default_value = (0.55, 0.55, 0.52, 1)
    g.link(g.coords(), b.inputs["Vector"])
    g.link(b.outputs["Color"], g.bsdf.inputs["Base Color"])
    _value(g, "Roughness", 0.2)
    g.bump(b.outputs["Fac"], 0.4)


def concrete(mat, hsv):
    """Sealed concrete: mottled greys with pores."""
    g = Graph(mat)
    v = g.coords()
    n = g.noise(v, 4.0, detail=10.0, roughness=0.7)
    grey = hsv_linear((hsv[0], 0.05, 0.45 + 0.3 * hsv[2]))
    g.link(g.ramp(n.outputs["Fac"], [(0.3, scaled(grey, 0.7)), (0.7, grey)]),
           g.bsdf.inputs["Base Color"])  # fmt: skip
    pores = g.node("ShaderNodeTexVoronoi", feature="F1")
    pores.inputs["Scale"].default_value = 300.0
    g.link(v, pores.inputs["Vector"])
    _value(g, "Roughness", 0.75)
    g.bump(pores.outputs["Distance"], 0.15)


def brushed_metal(mat, rgb=(0.8, 0.8, 0.8), roughness=0.3):
    """Brushed metal: anisotropic reflection along X, streaks from stretched noise."""
    g = Graph(mat)
    streaks = g.noise(g.coords((1.0, 400.0, 400.0)), 1.0, detail=2.0)
    _color(g, "Base Color", rgb)
    _value(g, "Metallic", 1.0)
    _value(g, "Anisotropic", 0.7)
    g.link(g.ramp(streaks.outputs["Fac"], [(0.3, (roughness * 0.7,) * 3), (0.7, (roughness,) * 3)]),
           g.bsdf.inputs["Roughness"])  # fmt: skip


def plain(mat, rgb, roughness=0.5, metallic=0.0, coat=0.0):
    g = Graph(mat)
    _color(g, "Base Color", rgb)
    _value(g, "Roughness", roughness)
    _value(g, "Metallic", metallic)
    _value(g, "Coat Weight", coat)


def table_material(mat, t):
    kind = t["kind"]
    if kind == "wood":
        wood(mat, t["hsv"], t["grain_scale"], t["grain_angle"], t["roughness"])
    elif kind == "laminate":
        laminate(mat, t["hsv"], t["grain_scale"], t["grain_angle"])
    elif kind == "stone":
        stone(mat, t["hsv"], 0.15 + 0.3 * t["roughness"])
    elif kind == "cloth":
        cloth(mat, t["hsv"])
    else:
        raise ValueError(f"unknown table kind '{kind}'")


def floor_material(mat, f):
    {"parquet": parquet, "tiles": tiles, "concrete": concrete}[f["kind"]](mat, f["hsv"])


# Object finishes by catalog id (the built-in objects' real materials);
# anything else, a YCB mesh of another object included, is plastic.
FINISHES = {
    "001_chips_can": "paper",
    "006_mustard_bottle": "plastic",
    "010_potted_meat_can": "tinplate",
    "011_banana": "fruit",
    "018_plum": "fruit",
    "019_pitcher_base": "plastic",
    "025_mug": "ceramic",
    "029_plate": "ceramic",
    "031_spoon": "steel",
    "033_spatula": "plastic",
    "037_scissors": "plastic",
    "040_large_marker": "plastic",
    "048_hammer": "painted_wood",
    "055_baseball": "leather",
    "red_wood_block": "painted_wood",
}


def finish_of(object_id):
    return FINISHES.get(object_id, "plastic")


def object_finish(mat, finish, rgb, wear):
    """The object's material: its colour (linear) with the finish of what
    the object is made of; `wear` in [0, 1] varies the detail."""
    g = Graph(mat)
    v = g.coords()
    _color(g, "Base Color", rgb)
    if finish == "ceramic":
        # A glossy glaze over a satin body, with a faint orange-peel relief.
        _value(g, "Roughness", 0.35)
        _value(g, "Coat Weight", 1.0)
        _value(g, "Coat Roughness", 0.02 + 0.05 * wear)
        g.bump(g.noise(v, 300.0, detail=2.0).outputs["Fac"], 0.05)
    elif finish == "plastic":
        _value(g, "Roughness", 0.22 + 0.3 * wear)
        _value(g, "Specular IOR Level", 0.55)
        _value(g, "Subsurface Weight", 0.0)
    elif finish == "tinplate":
        # Lacquered tin: a coloured metal with a clear coat and fine streaks.
        _value(g, "Metallic", 0.85)
        _value(g, "Roughness", 0.18 + 0.15 * wear)
        _value(g, "Anisotropic", 0.5)
        _value(g, "Coat Weight", 0.8)
        g.bump(g.noise(g.coords((1.0, 1.0, 500.0)), 1.0).outputs["Fac"], 0.03)
    elif finish == "steel":
        _color(g, "Base Color", (0.78, 0.78, 0.76))
        _value(g, "Metallic", 1.0)
        _value(g, "Roughness", 0.15 + 0.2 * wear)
        _value(g, "Anisotropic", 0.6)
    elif finish == "fruit":
        # Waxy skin with darker speckles.
        spots = g.noise(v, 120.0, detail=2.0)
        speck = g.ramp(spots.outputs["Fac"], [(0.62, rgb), (0.7, scaled(rgb, 0.45))])
        g.link(speck, g.bsdf.inputs["Base Color"])
        _value(g, "Roughness", 0.5)
        _value(g, "Coat Weight", 0.4)
        _value(g, "Coat Roughness", 0.25)
        _value(g, "Sheen Weight", 0.3)
    elif finish == "paper":
        # A printed cardboard tube: a satin varnished label.
        _value(g, "Roughness", 0.5)
        _value(g, "Coat Weight", 0.35)
        _value(g, "Coat Roughness", 0.2)
    elif finish == "leather":
        _value(g, "Roughness", 0.65)
        _value(g, "Sheen Weight", 0.4)
        g.bump(g.noise(v, 500.0, detail=3.0).outputs["Fac"], 0.2)
    elif finish == "painted_wood":
        grain = g.node("ShaderNodeTexWave", wave_type="BANDS", bands_direction="X")
        grain.inputs["Scale"].default_value = 40.0
        grain.inputs["Distortion"].default_value = 6.0
        g.link(v, grain.inputs["Vector"])
        _value(g, "Roughness", 0.55 - 0.2 * wear)
        g.bump(grain.outputs["Fac"], 0.12)
    else:
        raise ValueError(f"unknown finish '{finish}'")


def pendant_shade(mat, rgb):
    """A lampshade of thin enamelled metal."""
    plain(mat, rgb, roughness=0.3, metallic=0.0, coat=0.6)
