"""Objects people interact with: primitive shapes, their anchors and signed distance.

An object's local frame has its origin at the centre of its footprint on the floor (so a pose
with y = 0 rests on the ground), +Y up. `size` is the bounding box (width x, height y, depth z).
Anchors are the grasp points (handles, table edges), in the local frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry.rotations import norm, quat_to_matrix

OBJECT_TYPES = ("box", "table", "canister")
DEFAULT_SIZES = {"box": (0.45, 0.35, 0.35), "table": (1.2, 0.74, 0.7), "canister": (0.3, 0.5, 0.3)}
TABLE_TOP = 0.05  # table-top thickness in metres
SIZE_RANGE = (0.1, 3.0)  # m: the smallest and largest side a drawn object gets
TABLE_LEG = 0.05  # square leg width


@dataclass
class ObjectSpec:
    type: str = "box"
    size: tuple[float, float, float] = DEFAULT_SIZES["box"]
    anchors: np.ndarray | None = None  # (K, 3) local; None = the type's default grasp points

    def __post_init__(self):
        if self.type not in OBJECT_TYPES:
            raise ValueError(f"unknown object type {self.type!r}; expected one of {OBJECT_TYPES}")
        self.size = tuple(float(s) for s in self.size)
        if self.anchors is None:
            self.anchors = default_anchors(self.type, self.size)
        self.anchors = np.asarray(self.anchors, dtype=np.float64).reshape(-1, 3)

    def mesh(self):
        """A trimesh.Trimesh of the shape in its local frame."""
        import trimesh
        w, h, d = self.size
        if self.type == "box":
            return trimesh.creation.box((w, h, d), trimesh.transformations.translation_matrix((0, h / 2, 0)))
        if self.type == "canister":
            m = trimesh.creation.cylinder(radius=min(w, d) / 2, height=h, sections=24)
            m.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0)))
            m.apply_translation((0, h / 2, 0))
            return m
        centres, halves = self.table_boxes()
        return trimesh.util.concatenate([trimesh.creation.box(2 * half, trimesh.transformations.translation_matrix(c))
                                         for c, half in zip(centres, halves)])

    def table_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """A table as boxes, the top then four legs: centres (5, 3) and half extents (5, 3), local."""
        w, h, d = self.size
        leg_h = (h - TABLE_TOP) / 2
        centres = [(0, h - TABLE_TOP / 2, 0)] + [(sx * (w / 2 - TABLE_LEG), leg_h, sz * (d / 2 - TABLE_LEG))
                                                 for sx in (-1, 1) for sz in (-1, 1)]
        halves = [(w / 2, TABLE_TOP / 2, d / 2)] + [(TABLE_LEG / 2, leg_h, TABLE_LEG / 2)] * 4
        return np.array(centres), np.array(halves)

    def sdf_local(self, p: np.ndarray) -> np.ndarray:
        """Signed distance (negative inside) of local points (..., 3) -> (...)."""
        w, h, d = self.size
        if self.type == "box":
            return _box_sdf(p - (0, h / 2, 0), (w / 2, h / 2, d / 2))
        if self.type == "canister":
            q = p - (0, h / 2, 0)
            radial = norm(q[..., [0, 2]]) - min(w, d) / 2
            vertical = np.abs(q[..., 1]) - h / 2
            outside = np.linalg.norm(np.stack([np.maximum(radial, 0), np.maximum(vertical, 0)], -1), axis=-1)
            return outside + np.minimum(np.maximum(radial, vertical), 0)
        centres, halves = self.table_boxes()
        out = _box_sdf(p - centres[0], halves[0])
        for c, half in zip(centres[1:], halves[1:]):
            out = np.minimum(out, _box_sdf(p - c, half))
        return out

    def penetration_local(self, p: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """How deep spheres at local points p (..., 3) of radii (broadcastable to (...)) sink
        into the object: max(radii - sdf, 0) -> (...). Only spheres that reach its bounding sphere
        are measured (the rest are 0 either way): the finishing asks this of every candidate
        elbow of every held frame."""
        from_centre = norm(p - (0, self.size[1] / 2, 0))
        radii = np.broadcast_to(radii, from_centre.shape)
        near = from_centre < 0.5 * np.linalg.norm(self.size) + radii
        depth = np.zeros(from_centre.shape)
        depth[near] = np.maximum(radii[near] - self.sdf_local(p[near]), 0.0)
        return depth

    def sdf_world(self, p: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """Signed distance of world points (..., P, 3) to the object at pose (..., 7) -> (..., P)."""
        return self.sdf_local(world_to_local(p, pose))


def _box_sdf(q: np.ndarray, half) -> np.ndarray:
    """Signed distance to boxes centred at 0: q (..., 3), half (..., 3) broadcastable -> (...)."""
    d = np.abs(q) - np.asarray(half)
    outside = np.maximum(d, 0)
    return np.sqrt(np.sum(outside * outside, axis=-1)) + np.minimum(np.max(d, axis=-1), 0)


GRIP_SIGNS = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)  # (K=4, 2): sx, sz
PALM = 0.02  # m from the surface to the wrist joint of a hand flat on it
NUM_ANCHORS = len(GRIP_SIGNS)


def drawn_size(kind: str, outline: np.ndarray, camera) -> tuple[float, float, float]:
    """The size (w, h, d) of an object drawn as `outline` (L, 2) through `camera` (a
    StoryboardCamera): the type's default size scaled so that its upright silhouette (facing +Z)
    is as wide and as tall as the drawing, width and depth together, each within SIZE_RANGE."""
    w, h, d = DEFAULT_SIZES[kind]
    scale = np.ptp(np.asarray(outline, float), axis=0) / np.maximum(_seen((w, h, d), camera), 1e-9)   # across, up
    across = float(np.clip(scale[0], SIZE_RANGE[0] / min(w, d), SIZE_RANGE[1] / max(w, d)))
    up = float(np.clip(scale[1], SIZE_RANGE[0] / h, SIZE_RANGE[1] / h))
    return (w * across, h * up, d * across)


def resized_outline(outline: np.ndarray, old: tuple[float, float, float], new: tuple[float, float, float],
                    camera) -> np.ndarray:
    """An outline (L, 2) drawn for an object of size `old` (w, h, d) redrawn for size `new`: scaled
    across and up as its upright silhouette (facing +Z, as drawn_size reads it) grows, about the
    middle of its bottom edge (what rests on the floor stays on it). Typed sizes left a box's
    drawing as it was, its grips shown off it."""
    outline = np.asarray(outline, float)
    bottom = np.array([(outline[:, 0].min() + outline[:, 0].max()) / 2, outline[:, 1].min()])
    return bottom + (outline - bottom) * _seen(new, camera) / np.maximum(_seen(old, camera), 1e-9)


def _seen(size: tuple[float, float, float], camera) -> np.ndarray:
    """How wide and tall (2,) an upright box of `size` (w, h, d) facing +Z looks through `camera`."""
    w, h, d = size
    corners = np.array([[sx * w / 2, y, sz * d / 2] for sx in (-1, 1) for y in (0.0, h) for sz in (-1, 1)])
    return np.ptp(camera.project(corners), axis=0)


def default_anchors(kind: str, size: tuple[float, float, float]) -> np.ndarray:
    """(4, 3) grip points where the wrist joint is when the palm is on the surface, ordered
    [(-x,-z), (-x,+z), (+x,-z), (+x,+z)]: two on each x end, so two people holding the two
    ends, or one person holding the near side, each have a grip for each hand."""
    w, h, d = size
    if kind == "table":      # at the top's edge on the two short ends, palm under it
        a, y, b = w / 2 + PALM, h - TABLE_TOP - PALM, 0.3 * d
    elif kind == "canister":  # on the wall, 35 degrees either side of the x axis
        r = min(w, d) / 2 + PALM
        a, y, b = r * np.cos(np.radians(35)), 0.7 * h, r * np.sin(np.radians(35))
    else:                    # box: high on the end faces, where a lifting hand goes
        a, y, b = w / 2 + PALM, 0.75 * h, 0.28 * d
    return np.column_stack([GRIP_SIGNS[:, 0] * a, np.full(len(GRIP_SIGNS), y), GRIP_SIGNS[:, 1] * b])


def local_to_world(p: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Local points (..., P, 3) under pose (..., 7: xyz + wxyz) -> world (..., P, 3)."""
    R = quat_to_matrix(pose[..., 3:])
    return p @ np.swapaxes(R, -1, -2) + pose[..., None, :3]


def world_to_local(p: np.ndarray, pose: np.ndarray) -> np.ndarray:
    R = quat_to_matrix(pose[..., 3:])
    return (p - pose[..., None, :3]) @ R
