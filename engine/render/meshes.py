"""Unit meshes the shaders instance, and object meshes as vertex arrays.

All triangles wind counter-clockwise seen from outside.
"""
from __future__ import annotations

import numpy as np

from ..objects import ObjectSpec


def unit_ring(segments: int = 14) -> np.ndarray:
    """Open cylinder for capsule.vert: (6 * segments, 3) float32 rows of cos, sin, t."""
    a = np.linspace(0.0, 2 * np.pi, segments + 1)
    cos, sin = np.cos(a), np.sin(a)
    tris = []
    for i in range(segments):
        b0, b1 = (cos[i], sin[i], 0.0), (cos[i + 1], sin[i + 1], 0.0)
        t0, t1 = (cos[i], sin[i], 1.0), (cos[i + 1], sin[i + 1], 1.0)
        # The axis runs along u x v, so counter-clockwise seen from outside is b0, b1, t1.
        tris += [b0, b1, t1, b0, t1, t0]
    return np.asarray(tris, np.float32)


def unit_quad() -> np.ndarray:
    """(6, 2) float32 two triangles with corners at -1 / +1."""
    return np.array([(-1, -1), (1, -1), (1, 1), (-1, -1), (1, 1), (-1, 1)], np.float32)


def ribbon_quad() -> np.ndarray:
    """(6, 2) float32 corners for path.vert: x 0..1 along the segment, y -1 / +1 across."""
    return np.array([(0, -1), (1, -1), (1, 1), (0, -1), (1, 1), (0, 1)], np.float32)


def object_triangles(spec: ObjectSpec) -> np.ndarray:
    """(T * 3, 6) float32 position + normal rows in the object's local frame, hard edges kept."""
    m = spec.mesh().smooth_shaded  # splits vertices at sharp edges so box faces stay flat
    v = np.concatenate([m.vertices, m.vertex_normals], axis=1)
    return np.asarray(v[m.faces].reshape(-1, 6), np.float32)
