"""Motion warping onto the storyboard's keyposes and pelvis paths (Witkin and Popovic, 1995).

A generated motion follows its sketch only roughly. At every keyframe the warp solves the pose
that lands exactly on the sketched keypose in the sketch plane, and along every pelvis stroke
the root position that lies on the stroke; the differences (each joint's displacement from the
pelvis in the body's own frame, an offset of the root) are spread over the neighbouring frames,
so the motion keeps its own dynamics while passing through the sketch.

A 2D sketch does not give depth; the ground does. Every joint slides along its camera ray to
where its bone keeps its length (on the side nearer the generated pose), and the whole figure
then slides along the camera's viewing direction, which keeps the sketch exact, until its lower
foot stands on the ground. Pelvis paths are lifted the same way: the body moves to where the
stroke's ray meets the pelvis height at which the lower foot touches the ground.

Joint arrays are (N, H, 22, 3) in metres with consistent bone lengths: `offsets` (H, 22, 3) are
each person's bones, FK(joints[:, h, 0], IK(joints[:, h], offsets[h]), offsets[h]) == joints.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..camera import StoryboardCamera
from ..controls import closest_on_polyline
from ..skeleton import FEET, JOINT_INDEX, NUM_JOINTS, PARENTS, forward_kinematics, inverse_kinematics
from ..storyboard import Storyboard
from ..synth.reach import UP, heading_of, yaw_matrix
from ..synth.trajectory import smoothstep

PELVIS, L_HIP, R_HIP = JOINT_INDEX["pelvis"], JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]
LEVEL = 0.05  # |vertical part of the viewing direction| below which the camera is too level to
              # place points by their height


@dataclass
class WarpConfig:
    falloff: int = 12             # frames over which an offset fades in before the first key / out after the last
    path_smoothing: float = 4.0   # frames; Gaussian sigma of the per-frame path offsets
    path_passes: int = 2          # smoothing pulls points off the stroke a little; project again
    path_tolerance: float = 0.03  # m in the sketch plane; closer than this to its stroke, a pelvis is
                                  # left alone (a hand-drawn stroke wobbles; the walk should not)
    foot_height: float = 0.02     # m; height of the foot joint standing on the ground (as FeetConfig's)


LIMBS = [JOINT_INDEX[n] for n in ("l_knee", "r_knee", "l_ankle", "r_ankle", "l_elbow", "r_elbow",
                                  "l_wrist", "r_wrist", "spine1", "spine2", "spine3", "neck")]


def sketched_scale(offsets: np.ndarray, storyboard: Storyboard, agent: int, quantile: float = 0.9,
                   most: float = 1.1) -> float:
    """How much larger than `offsets` (22, 3) the agent's sketched keyposes say the body is, in
    [1, most].

    A bone's sketched length is at most its true length (foreshortening only shortens), so the
    long bones that lie nearly in the sketch plane tell the scale: a high quantile of sketched /
    own length over the keyposes' limbs and spine. A body only grows by this: a sketch cannot say
    a body is smaller, since every bone may point at the camera. Nor much larger: people built
    unlike the training bodies (the salsa dancers' longer bones, bent knees) would be scaled
    whole and lifted off their feet between keyposes; 1.1 measured best on held-out synthesized
    and real storyboards alike."""
    lengths = np.linalg.norm(offsets, axis=-1)
    ratios = [np.linalg.norm(k.points[j] - k.points[PARENTS[j]]) / lengths[j]
              for k in storyboard.keyposes if k.agent == storyboard.agents[agent].id
              for j in LIMBS if k.mask[j] and k.mask[PARENTS[j]] and lengths[j] > 1e-6]
    return float(np.clip(np.quantile(ratios, quantile), 1.0, most)) if ratios else 1.0


def _ray_depth(camera: StoryboardCamera, uv: np.ndarray, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ray through sketch point uv (2,) as origin (3,) + s * back, and the s of `point` (3,) on it."""
    right, up, back = camera.basis()
    origin = np.asarray(camera.target) + uv[0] * right + uv[1] * up
    return origin, float((point - origin) @ back)


def _grounding_height(joints: np.ndarray, foot_height: float) -> np.ndarray:
    """How far (...) poses (..., 22, 3) must move up for their lower foot to stand on the ground."""
    return foot_height - joints[..., list(FEET), 1].min(-1)


def solve_keypose(joints: np.ndarray, uv: np.ndarray, mask: np.ndarray, camera: StoryboardCamera,
                  lengths: np.ndarray, foot_height: float) -> np.ndarray:
    """One person's pose (22, 3) moved onto a sketched keypose: uv (22, 2) where mask (22,) is
    True; `lengths` (22,) the bone lengths to keep. Unsketched joints ride rigidly on their parent;
    the figure is grounded by sliding along the viewing direction (not for a level camera)."""
    back = camera.basis()[2]
    out = joints.copy()
    for j in range(NUM_JOINTS):
        p = PARENTS[j]
        if not mask[j]:
            out[j] = joints[j] if p < 0 else out[p] + joints[j] - joints[p]
            continue
        origin, s_now = _ray_depth(camera, uv[j], joints[j])
        if p < 0:  # the pelvis keeps its height; a level camera keeps its depth instead
            s = (joints[j, 1] - origin[1]) / back[1] if abs(back[1]) > LEVEL else s_now
            out[j] = origin + s * back
            continue
        # |origin + s back - parent| = length: a quadratic in s; the root nearer the pose wins.
        d = origin - out[p]
        half_b, c = d @ back, d @ d - lengths[j] ** 2
        disc = half_b ** 2 - c
        if disc < 0:  # the sketched bone is longer than the bone: point it at the ray's nearest point
            target = origin - half_b * back
            out[j] = out[p] + lengths[j] * (target - out[p]) / max(np.linalg.norm(target - out[p]), 1e-9)
            continue
        roots = -half_b + np.array([-1.0, 1.0]) * np.sqrt(disc)
        out[j] = origin + roots[np.argmin(np.abs(roots - s_now))] * back
    if abs(back[1]) > LEVEL:
        out += _grounding_height(out, foot_height) / back[1] * back
    return out


def spread(n: int, keys: list[int], values: np.ndarray, falloff: int) -> np.ndarray:
    """Offsets at sorted key frames, values (K, ...), spread over n frames -> (n, ...): linear
    between keys, fading to zero over `falloff` frames (smoothstep) before the first and after
    the last."""
    frames = np.arange(n)
    keys_arr = np.asarray(keys, float)
    flat = values.reshape(len(keys), -1)
    out = np.stack([np.interp(frames, keys_arr, flat[:, i]) for i in range(flat.shape[1])], -1)
    gap = np.maximum(keys_arr[0] - frames, frames - keys_arr[-1]).clip(min=0)
    return (out * smoothstep(1.0 - gap / max(falloff, 1))[:, None]).reshape((n,) + values.shape[1:])


def warp_to_keyposes(joints: np.ndarray, offsets: np.ndarray, storyboard: Storyboard,
                     config: WarpConfig = WarpConfig()) -> np.ndarray:
    """Every person passes through their sketched keyposes (exactly in the sketch plane, where
    bone lengths allow). joints (N, H, 22, 3), offsets (H, 22, 3) -> (N, H, 22, 3).

    The offsets spread between keys are joint displacements relative to the pelvis, in the
    body's own (heading) frame, so they turn with the body; the skeleton is then refitted. Local
    rotation offsets would be the textbook choice, but a solved keypose often tilts the IK's
    pelvis frame by 60 degrees or more and the hips back by as much; half of each, between keys,
    folds the legs up off the ground (a carrier crawled through the let_go example)."""
    out = joints.copy()
    n = len(joints)
    for h, agent in enumerate(storyboard.agents):
        keys = sorted((k for k in storyboard.keyposes if k.agent == agent.id and k.mask.any()),
                      key=lambda k: k.frame)
        if not keys:
            continue
        lengths = np.linalg.norm(offsets[h], axis=-1)
        frames = [k.frame for k in keys]
        posed = np.stack([solve_keypose(joints[k.frame, h], k.points, k.mask, storyboard.camera, lengths,
                                        config.foot_height) for k in keys])      # (K, 22, 3)
        body = joints[:, h] - joints[:, h, PELVIS:PELVIS + 1]                     # (N, 22, 3) from the pelvis
        hips = joints[:, h, L_HIP] - joints[:, h, R_HIP]
        turn = yaw_matrix(heading_of(np.cross(hips, UP)))                         # (N, 3, 3) body -> world
        moved = posed - posed[:, PELVIS:PELVIS + 1] - body[frames]
        local = np.einsum("kji,kpj->kpi", turn[frames], moved)                   # world -> body frame
        root = joints[:, h, PELVIS] + spread(n, frames, posed[:, PELVIS] - joints[frames, h, PELVIS], config.falloff)
        target = root[:, None] + body + np.einsum("nij,npj->npi", turn, spread(n, frames, local, config.falloff))
        out[:, h] = forward_kinematics(root, inverse_kinematics(target, offsets[h]), offsets[h])
    return out


def follow_paths(joints: np.ndarray, storyboard: Storyboard, config: WarpConfig = WarpConfig()) -> np.ndarray:
    """People whose pelvis has a stroke walk on it: over the stroke's span the body moves so its
    pelvis projects onto the nearest point of the stroke with the lower foot on the ground; the
    offset is smoothed and fades out around the span. joints (N, H, 22, 3) -> same."""
    out = joints.copy()
    n, cam = len(joints), storyboard.camera
    level = abs(cam.basis()[2, 1]) <= LEVEL
    for stroke in storyboard.trajectories:
        if stroke.joint != "pelvis" or level:
            continue
        h = storyboard.agent_index(stroke.agent)
        span = np.arange(stroke.start, min(stroke.end, n - 1) + 1)
        for _ in range(config.path_passes):
            pelvis = out[span, h, PELVIS]
            uv = cam.project(pelvis)
            off = closest_on_polyline(uv, stroke.points) - uv
            dist = np.linalg.norm(off, axis=-1, keepdims=True)
            on_stroke = uv + off * np.clip(1.0 - config.path_tolerance / np.maximum(dist, 1e-9), 0.0, None)
            height = pelvis[:, 1] + _grounding_height(out[span, h], config.foot_height)
            lifted = cam.unproject_to_height(on_stroke, height)
            shift = gaussian_filter1d(lifted - pelvis, config.path_smoothing, axis=0, mode="nearest")
            # The span's offsets, held at its ends and faded out beyond them.
            full = spread(n, list(span), shift, config.falloff)
            out[:, h] += full[:, None, :]
    return out
