"""The foreign test world (`[render] world = "foreign"`): a scene builder and
render path of its own, which no training set draws from.

It shares with training only what the plan fixes (the room and table
footprint, the object, the camera poses and intrinsics); everything that
makes pixels is built here with other geometry and other nodes: a furnished
room with a window onto a procedural sky, a table of wood, laminate, stone
or cloth, object finishes by material (glaze, plastic, metal, ...), its own
prosthetic hand, a lens with distortion, vignetting, rolling shutter and
another tone curve, and another Cycles integrator setting. It ignores the
plan's `appearance`; its own values are drawn per sequence by `draw.py`
from the plan's stream seed, outside every random stream of the planner.

One module per concern: draw (the per-sequence values, no bpy), materials,
room, lights, camera, render (integrator and compositor), worker.
"""
