"""Storyboard -> control tensors: the fixed-shape conditioning that encoders, energies and
the sampler read. One function, `build_controls`, with numpy outputs (torch converts cheaply).

Shapes for a storyboard of N frames, H agents, O objects (K anchors max):
  kp2d     (N, H, 22, 2)  keypose joint targets in the sketch plane at their keyframes
  kp_mask  (N, H, 22)     bool, a keypose joint is given at that frame
  tr2d     (N, H, 22, 2)  per-frame trajectory targets: each stroke resampled uniformly in
                          arc length over its frame span
  tr_mask  (N, H, 22)     bool
  obj2d    (N, O, 4)      object box at object-key frames: centre u, v, width, height
  obj_mask (N, O)         bool
  objpath2d (N, O, 2)     object path targets per frame (resampled like trajectories), the
                          object's base's (base_path)
  objpath_mask (N, O)     bool
  contact  (N, H, 2)      bool, hand (left, right) of agent h is told to hold something
  contact_anchor (N, H, 2) int, flat index o*K + k of the anchor held (-1 when none or a hand)
  camera   (3, 3)         rows right, up, back of the storyboard camera
  cam_target (3,)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry.polylines import point_polyline_distance, resample_polyline
from .skeleton import JOINT_INDEX, NUM_JOINTS
from .storyboard import HANDS, ObjectPath, Storyboard, Trajectory


@dataclass
class Controls:
    kp2d: np.ndarray
    kp_mask: np.ndarray
    tr2d: np.ndarray
    tr_mask: np.ndarray
    obj2d: np.ndarray
    obj_mask: np.ndarray
    objpath2d: np.ndarray
    objpath_mask: np.ndarray
    contact: np.ndarray
    contact_anchor: np.ndarray
    camera: np.ndarray
    cam_target: np.ndarray

    @property
    def chi(self) -> np.ndarray:
        """The paper's chi (N, H, 22): joint j of human h is constrained at frame n."""
        return self.kp_mask | self.tr_mask


def stroke_per_frame(stroke: Trajectory | ObjectPath) -> np.ndarray:
    """A stroke's sketch point at each frame of its span (end - start + 1, 2): evenly along it in
    arc length, as the model reads it."""
    return resample_polyline(stroke.points, stroke.end - stroke.start + 1)


def base_path(sb: Storyboard, path: ObjectPath) -> np.ndarray:
    """An object path's points (L, 2) as its base's (the centre of its footprint). A storyboard's
    object path is its base's (engine.sketchify traces it so, and the model learned it so), but an
    artist drawing in the app traces the box itself, through the middle of its outlines: a path
    that passes the centres of the object's outlines within its span closer, by more than half
    the object's projected half height, than it passes their bases is read as the centre's, and
    moved down by that half height (an orthographic view: the same shift at every point). A
    stroke's wobble is less than that margin; a box lifted straight up passes both."""
    keys = [k for k in sb.object_keys if k.object == path.object and path.start <= k.frame <= path.end]
    if not keys:
        return path.points
    spec = sb.objects[sb.object_index(path.object)].spec
    half = sb.camera.project(np.array([0.0, spec.size[1] / 2, 0.0])) - sb.camera.project(np.zeros(3))
    centres = np.stack([(k.outline.min(axis=0) + k.outline.max(axis=0)) / 2 for k in keys])
    to_centres = point_polyline_distance(centres, path.points).mean()
    to_bases = point_polyline_distance(centres - half, path.points).mean()
    return path.points - half if to_bases - to_centres > 0.5 * np.linalg.norm(half) else path.points


def build_controls(sb: Storyboard) -> Controls:
    n, h, o = sb.length, len(sb.agents), len(sb.objects)
    k_max = max([len(ob.spec.anchors) for ob in sb.objects] + [1])
    c = Controls(
        kp2d=np.zeros((n, h, NUM_JOINTS, 2)), kp_mask=np.zeros((n, h, NUM_JOINTS), bool),
        tr2d=np.zeros((n, h, NUM_JOINTS, 2)), tr_mask=np.zeros((n, h, NUM_JOINTS), bool),
        obj2d=np.zeros((n, o, 4)), obj_mask=np.zeros((n, o), bool),
        objpath2d=np.zeros((n, o, 2)), objpath_mask=np.zeros((n, o), bool),
        contact=np.zeros((n, h, 2), bool), contact_anchor=np.full((n, h, 2), -1, np.int64),
        camera=sb.camera.basis(), cam_target=np.asarray(sb.camera.target, float))
    for kp in sb.keyposes:
        a = sb.agent_index(kp.agent)
        c.kp2d[kp.frame, a][kp.mask] = kp.points[kp.mask]
        c.kp_mask[kp.frame, a] |= kp.mask
    for tr in sb.trajectories:
        a, j = sb.agent_index(tr.agent), JOINT_INDEX[tr.joint]
        c.tr2d[tr.start:tr.end + 1, a, j] = stroke_per_frame(tr)
        c.tr_mask[tr.start:tr.end + 1, a, j] = True
    for key in sb.object_keys:
        i = sb.object_index(key.object)
        lo, hi = key.outline.min(axis=0), key.outline.max(axis=0)
        c.obj2d[key.frame, i] = [*(lo + hi) / 2, *(hi - lo)]
        c.obj_mask[key.frame, i] = True
    for p in sb.object_paths:
        i = sb.object_index(p.object)
        c.objpath2d[p.start:p.end + 1, i] = resample_polyline(base_path(sb, p), p.end - p.start + 1)
        c.objpath_mask[p.start:p.end + 1, i] = True
    for ct in sb.contacts:
        a, hand = sb.agent_index(ct.agent), HANDS.index(ct.hand)
        c.contact[ct.start:ct.end + 1, a, hand] = True
        if ct.object is not None:
            c.contact_anchor[ct.start:ct.end + 1, a, hand] = sb.object_index(ct.object) * k_max + ct.anchor
    return c
