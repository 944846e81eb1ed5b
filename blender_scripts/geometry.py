"""Thin trimesh wrapper for the Rust side's batched geometric queries.

Arrays cross the Rust/Python boundary as little-endian bytes (float64 for
coordinates, uint32 for triangle indices) so a batch costs one copy, not one
Python object per number. trimesh picks Embree for rays when `embreex` is
installed and falls back to its rtree-based intersector otherwise.
"""

import numpy as np
import trimesh
from trimesh.ray import ray_triangle


def _array(data: bytes, dtype: str, columns: int) -> np.ndarray:
    return np.frombuffer(data, dtype=dtype).reshape(-1, columns)


class MeshQuery:
    """A mesh and its ray intersector, built once and queried in batches."""

    def __init__(self, vertices: bytes, faces: bytes, embree: bool = True):
        self.mesh = trimesh.Trimesh(
            vertices=_array(vertices, "<f8", 3).copy(),
            faces=_array(faces, "<u4", 3).astype(np.int64),
            process=False,
        )
        # mesh.ray is Embree's intersector when embreex imports.
        self.ray = self.mesh.ray if embree else ray_triangle.RayMeshIntersector(self.mesh)

    @property
    def is_watertight(self) -> bool:
        return bool(self.mesh.is_watertight)

    @property
    def backend(self) -> str:
        return type(self.ray).__module__.rsplit(".", 1)[-1]

    def first_hits(self, origins: bytes, directions: bytes) -> bytes:
        """Distance to the first hit per ray (float64 bytes, NaN for a miss)."""
        o = _array(origins, "<f8", 3)
        d = _array(directions, "<f8", 3)
        out = np.full(len(o), np.nan)
        if len(o) == 0:
            return out.astype("<f8").tobytes()
        _, index_ray, locations = self.ray.intersects_id(
            o, d, multiple_hits=False, return_locations=True
        )
        if len(index_ray):
            out[index_ray] = np.linalg.norm(locations - o[index_ray], axis=1)
        return out.astype("<f8").tobytes()

    def contains(self, points: bytes) -> bytes:
        """Whether each point lies inside the mesh (uint8 bytes, 1 = inside)."""
        p = _array(points, "<f8", 3)
        if len(p) == 0:
            return b""
        return self.ray.contains_points(p).astype(np.uint8).tobytes()

    def closest_points_trimesh(self, points: bytes) -> bytes:
        """trimesh's own closest-point query (distances), for benchmarks."""
        p = _array(points, "<f8", 3)
        _, distance, _ = trimesh.proximity.closest_point(self.mesh, p)
        return np.asarray(distance, dtype="<f8").tobytes()


def convex_hull(vertices: bytes) -> tuple[bytes, bytes]:
    """Convex hull of a point set: (float64 vertices, uint32 faces) bytes."""
    points = _array(vertices, "<f8", 3)
    hull = trimesh.convex.convex_hull(points)
    hull.fix_normals()
    return (
        np.asarray(hull.vertices, dtype="<f8").tobytes(),
        np.asarray(hull.faces, dtype="<u4").tobytes(),
    )
