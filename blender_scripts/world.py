"""The world: a dim constant background by default, or (per sequence) an
environment light from one of Blender's bundled studio-light HDRIs.

The room is a closed box, so light from the world or a sun reaches the table
only through an opening: while either shines the ceiling and its lamp are
hidden (a room open to the sky, like a courtyard or a skylight); the walls
keep their shadows. Light from any lamp inside the room is unchanged."""

import math
import os

import bpy

HDRI_DIR = ("studiolights", "world")


def hdri_path(name):
    """The bundled HDRI `name` (e.g. `city`), checked to exist."""
    folder = bpy.utils.system_resource("DATAFILES", path=os.path.join(*HDRI_DIR))
    path = os.path.join(folder or "", f"{name}.exr")
    if not os.path.isfile(path):
        raise ValueError(
            f"world HDRI '{name}' not found: {path} does not exist (the bpy wheel ships "
            "city, courtyard, forest, interior, night, studio, sunrise and sunset)"
        )
    return path


class World:
    def __init__(self):
        self.plain = bpy.data.worlds.new("world")
        self.plain.use_nodes = True
        background = self.plain.node_tree.nodes["Background"]
        background.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1)
        background.inputs["Strength"].default_value = 1.0
        self.hdri = bpy.data.worlds.new("world_hdri")
        self.hdri.use_nodes = True
        # A 256 px importance map instead of the HDRI's own 1K one: the map is
        # rebuilt as frames advance, and at 1 sample the 1K build doubled the
        # time of a frame (docs/rendering.md). Sampling stays unbiased.
        self.hdri.cycles.sampling_method = "MANUAL"
        self.hdri.cycles.sample_map_resolution = 256
        nodes, links = self.hdri.node_tree.nodes, self.hdri.node_tree.links
        coord = nodes.new("ShaderNodeTexCoord")
        self.mapping = nodes.new("ShaderNodeMapping")
        self.texture = nodes.new("ShaderNodeTexEnvironment")
        links.new(coord.outputs["Generated"], self.mapping.inputs["Vector"])
        links.new(self.mapping.outputs["Vector"], self.texture.inputs["Vector"])
        self.background = nodes["Background"]
        links.new(self.texture.outputs["Color"], self.background.inputs["Color"])
        bpy.context.scene.world = self.plain

    def apply(self, spec):
        """`spec`: a WorldLight dict, or None for the plain background."""
        scene = bpy.context.scene
        if spec is None:
            scene.world = self.plain
            return
        image = bpy.data.images.load(hdri_path(spec["hdri"]), check_existing=True)
        self.texture.image = image
        self.mapping.inputs["Rotation"].default_value = (
            0.0,
            0.0,
            math.radians(float(spec["rotation_deg"])),
        )
        self.background.inputs["Strength"].default_value = float(spec["strength"])
        scene.world = self.hdri
