"""Evaluation metrics, defined exactly as in DESIGN.md section 4. numpy in, floats out.

Units are metres on world joints; frames at the clip's fps; Y up. Joint arrays are
(N, H, 22, 3) unless stated. `adherence` gathers the figures one storyboard and one generated
clip (plus, when known, the 3D reference clip the storyboard was drawn from) allow.
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from .body import body_points
from .camera import StoryboardCamera
from .geometry.polylines import point_polyline_distance
from .objects import ObjectSpec, local_to_world, world_to_local
from .skeleton import FEET, HANDS, JOINT_INDEX

FOOT_CONTACT_HEIGHT = 0.05   # m
FOOT_SKATE_SPEED = 0.5       # m/s
FAILURE_THRESHOLDS = (0.2, 0.5)  # m, OmniControl-style failure rates
DEEP_PENETRATION = 0.04      # m

def foot_skate_ratio(joints: np.ndarray, fps: float, window: int = 1) -> float:
    """Share of frames in which a planted foot slides.

    joints: (N, 22, 3) one person, or (N, H, 22, 3) (the mean over people is returned).
    A foot (l_foot, r_foot) is in contact at frame n when its height is under 0.05 m at n and
    n + window (consecutive frames for window 1); such a frame skates when the foot's horizontal speed exceeds 0.5 m/s, the speed
    measured over `window` frames (1 = consecutive frames; DESIGN also reports 5).
    Ratio = skating frames / (N - window), a frame counting once if either foot skates.
    """
    joints = np.asarray(joints, float)
    if joints.ndim == 4:
        return float(np.mean([foot_skate_ratio(joints[:, h], fps, window) for h in range(joints.shape[1])]))
    n = joints.shape[0]
    if n <= window:
        return 0.0
    feet = joints[:, FEET]                                        # (N, 2, 3)
    low = feet[:, :, 1] < FOOT_CONTACT_HEIGHT
    contact = low[:-window] & low[window:]                        # (N - w, 2)
    horiz = np.linalg.norm(feet[window:, :, [0, 2]] - feet[:-window, :, [0, 2]], axis=-1)
    speed = horiz * fps / window
    skating = np.any(contact & (speed > FOOT_SKATE_SPEED), axis=1)
    return float(skating.sum() / (n - window))


# ---- control accuracy -------------------------------------------------------------------------

def keypose_errors_2d(joints: np.ndarray, kp2d: np.ndarray, kp_mask: np.ndarray,
                      camera: StoryboardCamera) -> np.ndarray:
    """Sketch-plane distance of each sketched keypoint to the projected joint.
    kp2d (N, H, 22, 2), kp_mask (N, H, 22) bool -> (M,) one per keypoint."""
    return np.linalg.norm(camera.project(joints)[kp_mask] - kp2d[kp_mask], axis=-1)


def keypose_errors_3d(joints: np.ndarray, target: np.ndarray, kp_mask: np.ndarray) -> np.ndarray:
    """World distance of each constrained joint to its 3D target (N, H, 22, 3) -> (M,)."""
    return np.linalg.norm(joints[kp_mask] - target[kp_mask], axis=-1)


def trajectory_errors_2d(joints: np.ndarray, storyboard) -> np.ndarray:
    """"Average" protocol in the sketch plane: distance of the projected joint to its stroke's
    polyline at every frame of the stroke's span -> (M,) one per constrained (frame, stroke)."""
    errors = [np.zeros(0)]
    for t in storyboard.trajectories:
        h, j = storyboard.agent_index(t.agent), JOINT_INDEX[t.joint]
        uv = storyboard.camera.project(joints[t.start:t.end + 1, h, j])
        errors.append(point_polyline_distance(uv, t.points))
    return np.concatenate(errors)


def trajectory_errors_3d(joints: np.ndarray, reference: np.ndarray, storyboard) -> np.ndarray:
    """"Average" protocol in the world: distance of the joint to the reference clip's path of
    that joint over the stroke's span (a polyline of its positions), at every frame of the
    span -> (M,)."""
    errors = [np.zeros(0)]
    for t in storyboard.trajectories:
        h, j = storyboard.agent_index(t.agent), JOINT_INDEX[t.joint]
        span = slice(t.start, t.end + 1)
        errors.append(point_polyline_distance(joints[span, h, j], reference[span, h, j]))
    return np.concatenate(errors)


def failure_rates(per_sequence_errors: Sequence[np.ndarray],
                  thresholds: Sequence[float] = FAILURE_THRESHOLDS) -> dict[str, float]:
    """Share of sequences with any constrained point farther than each threshold.
    per_sequence_errors: one array of constrained-point errors (m) per sequence."""
    worst = np.array([np.max(e, initial=0.0) for e in per_sequence_errors])
    return {f"fail@{th:g}": float(np.mean(worst > th)) if len(worst) else 0.0 for th in thresholds}


# ---- interaction ------------------------------------------------------------------------------

def object_position_error(obj_pose: np.ndarray, target: np.ndarray, mask: np.ndarray) -> float:
    """Mean distance of the object root (pose translation) to its target position.
    obj_pose (N, O, 7), target (N, O, 3), mask (N, O) bool frames with a target."""
    if not mask.any():
        return 0.0
    return float(np.mean(np.linalg.norm(obj_pose[..., :3][mask] - target[mask], axis=-1)))


def anchor_error(joints: np.ndarray, obj_anchors: np.ndarray, contact_anchor: np.ndarray) -> float:
    """Mean hand (wrist) to anchor distance over the (frame, hand) pairs with a storyboard
    object contact. obj_anchors (N, O, K, 3); contact_anchor (N, H, 2) flat o * K + k, -1 none."""
    held = contact_anchor >= 0
    if not held.any():
        return 0.0
    n, h = contact_anchor.shape[:2]
    anchors = obj_anchors.reshape(n, -1, 3)
    frame = np.broadcast_to(np.arange(n)[:, None, None], held.shape)
    target = anchors[frame[held], contact_anchor[held]]
    return float(np.mean(np.linalg.norm(joints[:, :, list(HANDS)][held] - target, axis=-1)))


def frame_penetration(joints: np.ndarray, obj_pose: np.ndarray | None = None,
                      objects: Sequence[ObjectSpec] = (), radii: np.ndarray | None = None) -> np.ndarray:
    """Deepest penetration per frame (N,), >= 0: of the body spheres into each object (radius
    minus the object's SDF), into another person's spheres (sum of radii minus distance), and
    of the joints below the ground (-y). `radii` (43,) overrides the body's sphere radii."""
    joints = np.asarray(joints, float)
    n, h = joints.shape[:2]
    points, default_radii = body_points(joints)                             # (N, H, 43, 3)
    radii = default_radii if radii is None else np.asarray(radii, float)
    depth = [np.max(-joints[..., 1], axis=(1, 2))]
    for o, spec in enumerate(objects):
        local = world_to_local(points.reshape(n, -1, 3), obj_pose[:, o])
        depth.append(np.max(spec.penetration_local(local, np.tile(radii, h)), axis=1))
    for a in range(h):
        for b in range(a + 1, h):
            dist = np.linalg.norm(points[:, a, :, None] - points[:, b, None], axis=-1)
            depth.append(np.max(radii[:, None] + radii[None] - dist, axis=(1, 2)))
    return np.maximum(np.max(depth, axis=0), 0.0)


def penetration(joints: np.ndarray, obj_pose: np.ndarray | None = None,
                objects: Sequence[ObjectSpec] = (), radii: np.ndarray | None = None) -> tuple[float, float]:
    """Pen: (mean over frames of the deepest penetration, share of frames deeper than 0.04 m)."""
    depth = frame_penetration(joints, obj_pose, objects, radii)
    return float(np.mean(depth)), float(np.mean(depth > DEEP_PENETRATION))


# ---- contact timing ---------------------------------------------------------------------------

def contact_f1(pred: np.ndarray, label: np.ndarray) -> float:
    """F1 of predicted vs labelled contact (any shape, bool). 1 when both have no contact."""
    pred, label = np.asarray(pred, bool), np.asarray(label, bool)
    tp = np.sum(pred & label)
    denom = pred.sum() + label.sum()
    return 1.0 if denom == 0 else float(2 * tp / denom)


def expected_calibration_error(prob: np.ndarray, label: np.ndarray, bins: int = 10) -> float:
    """ECE with `bins` equal-width probability bins: sum over bins of (share of samples) x
    |mean predicted probability - frequency of label 1|. prob, label: same shape."""
    prob, label = np.ravel(prob).astype(float), np.ravel(label).astype(float)
    if prob.size == 0:
        return 0.0
    which = np.minimum((prob * bins).astype(int), bins - 1)
    gap = np.abs(np.bincount(which, prob, bins) - np.bincount(which, label, bins))
    return float(gap.sum() / prob.size)


def brier_score(prob: np.ndarray, label: np.ndarray) -> float:
    """Mean squared difference between predicted probability and 0/1 label."""
    prob, label = np.ravel(prob).astype(float), np.ravel(label).astype(float)
    return float(np.mean((prob - label) ** 2)) if prob.size else 0.0


# ---- diversity and distribution metrics -------------------------------------------------------

def diversity(variations: np.ndarray) -> float:
    """Mean over pairs of variations of their mean per-joint distance (m).
    variations: (K, N, H, 22, 3) joints of K generations of one storyboard."""
    v = np.asarray(variations, float)
    k = v.shape[0]
    if k < 2:
        return 0.0
    a, b = np.triu_indices(k, 1)
    return float(np.mean(np.linalg.norm(v[a] - v[b], axis=-1)))


def frechet_distance(mu1: np.ndarray, sigma1: np.ndarray, mu2: np.ndarray, sigma2: np.ndarray) -> float:
    """Frechet distance between N(mu1, sigma1) and N(mu2, sigma2):
    |mu1 - mu2|^2 + tr(sigma1 + sigma2 - 2 (sigma1 sigma2)^(1/2))."""
    from scipy import linalg
    mu1, mu2 = np.atleast_1d(mu1).astype(float), np.atleast_1d(mu2).astype(float)
    s1, s2 = np.atleast_2d(sigma1).astype(float), np.atleast_2d(sigma2).astype(float)
    with warnings.catch_warnings():  # a singular product is handled just below
        warnings.simplefilter("ignore", linalg.LinAlgWarning)
        covmean = linalg.sqrtm(s1 @ s2)
        if not np.all(np.isfinite(covmean)):  # regularise as is customary for FID
            eps = 1e-6 * np.eye(len(s1))
            covmean = linalg.sqrtm((s1 + eps) @ (s2 + eps))
    covmean = np.real(covmean)  # imaginary parts are numerical noise
    diff = mu1 - mu2
    return float(diff @ diff + np.trace(s1) + np.trace(s2) - 2 * np.trace(covmean))


def r_precision(story_emb: np.ndarray, motion_emb: np.ndarray, top_k: int = 3, batch: int = 32) -> float:
    """Storyboard -> motion R-precision: in batches of `batch` matched pairs (row i of each
    belongs together), the share of storyboards whose own motion is among the `top_k` nearest
    (Euclidean) motions of the batch. Incomplete last batches are dropped, as is customary,
    unless there are fewer than `batch` pairs in all (then they form one batch)."""
    story, motion = np.asarray(story_emb, float), np.asarray(motion_emb, float)
    m = len(story)
    size = min(batch, m)
    hits = []
    for start in range(0, m - size + 1, size):
        s, mo = story[start:start + size], motion[start:start + size]
        dist = np.linalg.norm(s[:, None] - mo[None], axis=-1)                 # (b, b)
        rank = np.sum(dist < np.diag(dist)[:, None], axis=1)                  # motions strictly closer
        hits.append(rank < top_k)
    return float(np.mean(np.concatenate(hits))) if hits else 0.0


# ---- one storyboard ---------------------------------------------------------------------------

def adherence(clip, storyboard, reference=None) -> dict[str, float]:
    """How well a generated MotionClip follows its Storyboard; keys only for figures that apply:
    K2D, T2D (sketch plane); K3D, T3D, MPJPE, Pelvis, Obj (need the reference clip: MPJPE and
    Pelvis are the mean distances of all joints and of the pelvis to it); fail@0.2 / fail@0.5
    (this sequence's 0/1 failure flags on the 3D errors, or the 2D ones without a reference;
    their mean over sequences is the failure rate); Obj2D (projected object centre vs the
    sketched silhouette centre, and its base's distance to the object path's polyline, as T2D);
    Anc; Pen and Pen>4cm; FootSkate and FootSkate@5; ContactF1, ECE, Brier (the clip's CTMC
    contact + carry occupancy vs the frames with a storyboard contact)."""
    from .controls import base_path, build_controls
    c = build_controls(storyboard)
    joints = np.asarray(clip.joints, float)
    if joints.shape[:2] != c.kp_mask.shape[:2]:
        raise ValueError(f"clip has {joints.shape[0]} frames and {joints.shape[1]} people, the storyboard "
                         f"{storyboard.length} frames and {len(storyboard.agents)} agents")
    cam = storyboard.camera
    out: dict[str, float] = {}

    def put(name: str, errors: np.ndarray) -> None:
        if errors.size:
            out[name] = float(np.mean(errors))

    k2, t2 = keypose_errors_2d(joints, c.kp2d, c.kp_mask, cam), trajectory_errors_2d(joints, storyboard)
    put("K2D", k2)
    put("T2D", t2)
    constrained = np.concatenate([k2, t2])
    if reference is not None:
        ref = np.asarray(reference.joints, float)
        k3, t3 = keypose_errors_3d(joints, ref, c.kp_mask), trajectory_errors_3d(joints, ref, storyboard)
        put("K3D", k3)
        put("T3D", t3)
        put("MPJPE", np.linalg.norm(joints - ref, axis=-1))                    # every joint, every frame
        put("Pelvis", np.linalg.norm(joints[:, :, 0] - ref[:, :, 0], axis=-1))
        constrained = np.concatenate([k3, t3])
    if constrained.size:
        out.update(failure_rates([constrained]))

    specs = [o.spec for o in storyboard.objects]
    obj_pose = None if clip.obj_pose is None else np.asarray(clip.obj_pose, float)
    if obj_pose is not None and specs:
        targeted = c.obj_mask | c.objpath_mask
        if targeted.any():
            lift = np.array([[0.0, s.size[1] / 2, 0.0] for s in specs])
            centre = local_to_world(lift[None, :, None], obj_pose)[..., 0, :]      # (N, O, 3)
            base = cam.project(obj_pose[..., :3])                                   # what a path traces
            put("Obj2D", np.concatenate(
                [np.linalg.norm(cam.project(centre) - c.obj2d[..., :2], axis=-1)[c.obj_mask]]
                + [point_polyline_distance(base[p.start:p.end + 1, storyboard.object_index(p.object)],
                                           base_path(storyboard, p)) for p in storyboard.object_paths]))
            if reference is not None and reference.obj_pose is not None:
                out["Obj"] = object_position_error(obj_pose, np.asarray(reference.obj_pose, float)[..., :3],
                                                   targeted)
        if clip.obj_anchors is not None and (c.contact_anchor >= 0).any():
            out["Anc"] = anchor_error(joints, np.asarray(clip.obj_anchors, float), c.contact_anchor)
    pen, deep = penetration(joints, obj_pose, specs if obj_pose is not None else ())
    out["Pen"], out["Pen>4cm"] = pen, deep
    out["FootSkate"] = foot_skate_ratio(joints, clip.fps)
    out["FootSkate@5"] = foot_skate_ratio(joints, clip.fps, window=5)
    if clip.phase is not None and storyboard.contacts:
        prob = np.clip(clip.phase[:, 1] + clip.phase[:, 2], 0.0, 1.0)
        label = c.contact.any(axis=(1, 2))
        out["ContactF1"] = contact_f1(prob > 0.5, label)
        out["ECE"] = expected_calibration_error(prob, label)
        out["Brier"] = brier_score(prob, label)
    return out
