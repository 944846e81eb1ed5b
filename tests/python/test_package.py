import importlib


def test_blender_scripts_is_importable():
    module = importlib.import_module("blender_scripts")
    assert "Rust" in module.__doc__
