"""Unit meshes the shaders instance, and object meshes as vertex arrays.

Unit meshes are indexed: llvmpipe then runs the vertex shader once per corner, not once per
triangle that uses it. All triangles wind counter-clockwise seen from outside.
"""
from __future__ import annotations

import numpy as np

from ..objects import ObjectSpec


def unit_ring(segments: int = 14) -> tuple[np.ndarray, np.ndarray]:
    """Open cylinder for capsule.vert: vertices (2 * segments, 3) float32 rows of cos, sin, t
    (the bottom ring, then the top ring) and indices (6 * segments,) int32.
    """
    a = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], axis=1)
    vertices = np.concatenate([np.c_[ring, np.zeros(segments)], np.c_[ring, np.ones(segments)]])
    b0 = np.arange(segments)
    b1 = (b0 + 1) % segments
    t0, t1 = b0 + segments, b1 + segments
    # The axis runs along u x v, so counter-clockwise seen from outside is b0, b1, t1.
    indices = np.stack([b0, b1, t1, b0, t1, t0], axis=1).reshape(-1)
    return vertices.astype(np.float32), indices.astype(np.int32)


def unit_quad() -> tuple[np.ndarray, np.ndarray]:
    """Vertices (4, 2) float32, corners at -1 / +1, and indices (6,) int32 of its two triangles."""
    return (np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], np.float32),
            np.array([0, 1, 2, 0, 2, 3], np.int32))


def ribbon_quad() -> tuple[np.ndarray, np.ndarray]:
    """For path.vert: vertices (4, 2) float32, x 0..1 along the segment and y -1 / +1 across,
    and indices (6,) int32 of its two triangles."""
    return (np.array([(0, -1), (1, -1), (1, 1), (0, 1)], np.float32),
            np.array([0, 1, 2, 0, 2, 3], np.int32))


def object_triangles(spec: ObjectSpec) -> np.ndarray:
    """(T * 3, 6) float32 position + normal rows in the object's local frame, hard edges kept."""
    m = spec.mesh().smooth_shaded  # splits vertices at sharp edges so box faces stay flat
    v = np.concatenate([m.vertices, m.vertex_normals], axis=1)
    return np.asarray(v[m.faces].reshape(-1, 6), np.float32)
