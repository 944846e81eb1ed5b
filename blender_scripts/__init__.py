"""Thin Blender (bpy) and trimesh helpers called from the Rust generator.

Scene building and rendering only: planning, bookkeeping and I/O live in Rust.
"""
