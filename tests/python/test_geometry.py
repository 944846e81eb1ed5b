"""blender_scripts.geometry against analytic answers on a unit cube."""

import numpy as np
import pytest
import trimesh

from blender_scripts import geometry


def _cube_query(half: float = 0.5, embree: bool = True) -> geometry.MeshQuery:
    box = trimesh.creation.box(extents=[2 * half] * 3)
    return geometry.MeshQuery(
        np.asarray(box.vertices, dtype="<f8").tobytes(),
        np.asarray(box.faces, dtype="<u4").tobytes(),
        embree,
    )


@pytest.mark.parametrize("embree", [True, False])
def test_first_hits_distances_and_misses(embree):
    q = _cube_query(embree=embree)
    if not embree:
        assert q.backend == "ray_triangle"
    origins = np.array([[0, 0, 2.0], [0, 0, 0.0], [3, 3, 3.0]])
    dirs = np.array([[0, 0, -1.0], [1, 0, 0.0], [0, 0, 1.0]])
    out = np.frombuffer(q.first_hits(origins.tobytes(), dirs.tobytes()), dtype="<f8")
    assert np.allclose(out[:2], [1.5, 0.5], atol=1e-5)
    assert np.isnan(out[2])


@pytest.mark.parametrize("embree", [True, False])
def test_contains_and_watertight(embree):
    q = _cube_query(embree=embree)
    assert q.is_watertight
    pts = np.array([[0, 0, 0.0], [0.4, -0.4, 0.4], [0.6, 0, 0.0], [0, 0, -2.0]])
    inside = np.frombuffer(q.contains(pts.tobytes()), dtype=np.uint8)
    assert inside.tolist() == [1, 1, 0, 0]


def test_empty_batches():
    q = _cube_query()
    assert q.first_hits(b"", b"") == b""
    assert q.contains(b"") == b""


def test_convex_hull_of_points_is_closed_and_outward():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(500, 3))
    v, f = geometry.convex_hull(pts.tobytes())
    hull = trimesh.Trimesh(
        np.frombuffer(v, dtype="<f8").reshape(-1, 3),
        np.frombuffer(f, dtype="<u4").reshape(-1, 3).astype(np.int64),
    )
    assert hull.is_watertight
    assert hull.volume > 0
    assert hull.contains(np.zeros((1, 3)))[0]
