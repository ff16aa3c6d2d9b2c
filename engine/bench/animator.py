"""What an animator looks at before keeping a take, per generated clip (metres unless stated).

    Pop        largest one-frame pop of a joint: a jump beyond both neighbouring frames' motion,
               or a spike off the line between its neighbouring frames
    Grip       95th percentile over contact frames of a holding wrist's distance to its grip
    Wrist@key  mean 3D distance of the sketched wrists to the reference at their keys
    Key2D      mean sketch-plane distance of every placed key joint to its drawn point
    FootFloat  95th percentile over frames of each person's lowest foot above the floor
    Bone       largest change of a bone's length over the clip
    PenMax     deepest interpenetration of people and object in any frame
    Detour     how much further the pelvis bows in depth off its sketched path than the reference
    Timing     largest difference, between keys, of the share of the way covered (0-1) against
               the reference: "stands still, then hurries" scores high
`ANIMATOR_TARGETS` are the bounds every storyboard must meet (issue 18); FootSkate, the share of
frames a planted foot slides, is engine.metrics.adherence's.
"""
from __future__ import annotations

import numpy as np

from ..clip import MotionClip
from ..finishing.misses import GRIP_TOLERANCE, hold_gaps
from ..finishing.steady import frame_pops
from ..metrics import frame_penetration
from ..skeleton import FEET, JOINT_INDEX, PARENTS
from ..storyboard import Storyboard

ANIMATOR_TARGETS = {"Pop": 0.05, "Grip": GRIP_TOLERANCE, "Wrist@key": 0.08, "FootFloat": 0.06, "FootSkate": 0.03,
                    "PenMax": 0.02}
# Issue 18's first bounds on real held-out windows (engine.metrics.adherence's figures, m);
# the goal beyond them is 0.10 and 0.15.
REAL_TARGETS = {"Pelvis": 0.15, "MPJPE": 0.20}
WRISTS = (JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"])
PELVIS = JOINT_INDEX["pelvis"]
MIN_TRAVEL_M = 0.3     # key intervals shorter than this in the reference have no timing to judge


def animator_metrics(clip: MotionClip, storyboard: Storyboard, reference: MotionClip | None = None) -> dict[str, float]:
    joints = np.asarray(clip.joints, float)                                  # (N, H, 22, 3)
    out = {"Pop": pop(joints), "Grip": grip(clip, storyboard), "Key2D": key_error_2d(joints, storyboard),
           "FootFloat": foot_float(joints), "Bone": bone_change(joints),
           "PenMax": float(frame_penetration(joints, clip.obj_pose, [o.spec for o in storyboard.objects]).max())}
    if reference is not None:
        ref = np.asarray(reference.joints, float)
        out.update({"Wrist@key": wrist_at_keys(joints, ref, storyboard), "Detour": depth_detour(joints, ref, storyboard),
                    "Timing": timing(joints, ref, storyboard)})
    return out


def pop(joints: np.ndarray) -> float:
    """max over frames n and joints of the jump |x_n - x_n-1| - max(|x_n-1 - x_n-2|, |x_n+1 - x_n|)
    and of the spike |x_n - (x_n-1 + x_n+1) / 2| (smooth motion: a few millimetres)."""
    if len(joints) < 4:
        return 0.0
    return float(max(frame_pops(joints.reshape(len(joints), -1, 3)).max(), 0.0))


def grip(clip: MotionClip, storyboard: Storyboard) -> float:
    """95th percentile over (frame, hand) pairs in object contact spans of wrist-to-anchor distance."""
    gaps = [gap for _, _, gap in hold_gaps(clip, storyboard)]
    return float(np.percentile(np.concatenate(gaps), 95)) if gaps else 0.0


def key_error_2d(joints: np.ndarray, storyboard: Storyboard) -> float:
    errors = [np.linalg.norm(storyboard.camera.project(joints[k.frame, storyboard.agent_index(k.agent)])[k.mask]
                             - k.points[k.mask], axis=-1) for k in storyboard.keyposes]
    return float(np.mean(np.concatenate(errors))) if errors else 0.0


def wrist_at_keys(joints: np.ndarray, reference: np.ndarray, storyboard: Storyboard) -> float:
    errors = [np.linalg.norm(joints[k.frame, h, j] - reference[k.frame, h, j])
              for k in storyboard.keyposes for h in [storyboard.agent_index(k.agent)] for j in WRISTS if k.mask[j]]
    return float(np.mean(errors)) if errors else 0.0


def foot_float(joints: np.ndarray) -> float:
    lowest = joints[:, :, list(FEET), 1].min(-1)                             # (N, H)
    return float(np.percentile(lowest, 95))


def bone_change(joints: np.ndarray) -> float:
    lengths = np.linalg.norm(joints[:, :, 1:] - joints[:, :, list(PARENTS[1:])], axis=-1)   # (N, H, 21)
    return float(np.ptp(lengths, axis=0).max())


def _bow(depth: np.ndarray) -> float:
    """Largest distance of a depth curve (M,) from the chord between its ends."""
    chord = np.linspace(depth[0], depth[-1], len(depth))
    return float(np.abs(depth - chord).max())


def depth_detour(joints: np.ndarray, reference: np.ndarray, storyboard: Storyboard) -> float:
    """Over pelvis strokes: the pelvis' bow in camera depth beyond the reference's (0 when less)."""
    back = storyboard.camera.basis()[2]
    detours = [0.0]
    for t in storyboard.trajectories:
        if t.joint != "pelvis" or t.end - t.start < 2:
            continue
        h, span = storyboard.agent_index(t.agent), slice(t.start, t.end + 1)
        detours.append(_bow(joints[span, h, PELVIS] @ back) - _bow(reference[span, h, PELVIS] @ back))
    return float(max(detours))


def _progress(path: np.ndarray) -> np.ndarray:
    """Share of the ground path (M, 3) covered at each of its frames, 0 to 1."""
    step = np.linalg.norm(np.diff(path[:, [0, 2]], axis=0), axis=-1)
    covered = np.concatenate([[0.0], np.cumsum(step)])
    return covered / max(covered[-1], 1e-9)


def timing(joints: np.ndarray, reference: np.ndarray, storyboard: Storyboard) -> float:
    """Between each agent's consecutive keys where the reference travels MIN_TRAVEL_M or more."""
    worst = 0.0
    for agent in storyboard.agents:
        h = storyboard.agent_index(agent.id)
        frames = sorted({k.frame for k in storyboard.keyposes if k.agent == agent.id})
        for a, b in zip(frames, frames[1:]):
            ref_path = reference[a:b + 1, h, PELVIS]
            if b - a < 2 or np.linalg.norm(np.diff(ref_path[:, [0, 2]], axis=0), axis=-1).sum() < MIN_TRAVEL_M:
                continue
            worst = max(worst, float(np.abs(_progress(joints[a:b + 1, h, PELVIS]) - _progress(ref_path)).max()))
    return worst
