"""The figures an artist starts a keypose from: the canvas's standing template and a small pose
library (stand, walk stride, crouch-reach, lift, carry, hand over, shake hands, hold hands,
wave), each a 3D pose on the rest skeleton facing +Z, seen through the storyboard camera."""
from __future__ import annotations

import numpy as np

from .camera import StoryboardCamera
from .skeleton import JOINT_INDEX, PARENTS, rest_pose
from .synth.reach import pitch_matrix, two_bone_ik, yaw_matrix

J = JOINT_INDEX
# name -> (pelvis drop (m), {end joint: target relative to the standing pelvis (x left, y up, z forward)})
_LIBRARY = {
    "stand": (0.0, {}),
    "walk stride": (0.03, {"l_ankle": (0.09, -0.83, 0.28), "r_ankle": (-0.09, -0.85, -0.24),
                           "l_wrist": (0.2, -0.35, -0.18), "r_wrist": (-0.2, -0.33, 0.2)}),
    "crouch-reach": (0.38, {"l_ankle": (0.14, -0.86, -0.05), "r_ankle": (-0.14, -0.86, -0.05),
                            "l_wrist": (0.16, -0.55, 0.45), "r_wrist": (-0.16, -0.55, 0.45)}),
    "lift": (0.28, {"l_ankle": (0.16, -0.86, 0.0), "r_ankle": (-0.16, -0.86, 0.0),
                    "l_wrist": (0.2, -0.45, 0.38), "r_wrist": (-0.2, -0.45, 0.38)}),
    "carry": (0.02, {"l_wrist": (0.2, 0.05, 0.35), "r_wrist": (-0.2, 0.05, 0.35)}),
    "hand over": (0.0, {"l_wrist": (0.2, 0.2, 0.5), "r_wrist": (-0.2, 0.2, 0.5)}),   # held out in both hands
    "shake hands": (0.0, {"r_wrist": (-0.08, 0.15, 0.32)}),                            # the right hand held out
    "hold hands": (0.0, {"r_wrist": (-0.45, -0.12, 0.15)}),
    "wave": (0.0, {"r_wrist": (-0.35, 0.85, 0.1)}),
}
POSE_NAMES = tuple(_LIBRARY)
# What a pose's hands reach for: a stamp turns its reach towards the nearest one drawn then. A
# pick-up reaches for an object where it rests on the floor (drawn then or before), a carry for
# one drawn at that frame.
REACHES_FOR = {"hand over": "person", "shake hands": "person", "crouch-reach": "resting object",
               "lift": "resting object", "carry": "object"}
_LIMBS = {"l_wrist": ("l_shoulder", "l_elbow"), "r_wrist": ("r_shoulder", "r_elbow"),
          "l_ankle": ("l_hip", "l_knee"), "r_ankle": ("r_hip", "r_knee")}


def standing_pose_2d(camera: StoryboardCamera) -> np.ndarray:
    """A relaxed standing figure (arms down) seen through the storyboard camera, pelvis at the
    sketch origin: (22, 2) metres."""
    joints = rest_pose().copy()
    for side, sign in (("l_", 1.0), ("r_", -1.0)):
        shoulder = joints[JOINT_INDEX[side + "shoulder"]]
        elbow = shoulder + (0.04 * sign, -0.26, 0.0)
        joints[JOINT_INDEX[side + "elbow"]] = elbow
        joints[JOINT_INDEX[side + "wrist"]] = elbow + (0.02 * sign, -0.24, 0.05)
    uv = camera.project(joints)
    return uv - uv[0]


def library_pose(name: str, yaw: float = 0.0, hands: np.ndarray | None = None, reach: float = 1.0) -> np.ndarray:
    """A library pose in 3D (22, 3): the standing figure with its pelvis lowered and its hands and
    feet moved to the pose's places, elbows and knees solved by two-bone IK (elbows bend down
    and back, knees forward), facing +Z turned by `yaw` radians about the vertical through the
    pelvis (engine.facing's yaw). `hands` (2, 3): where the left and right wrists reach instead
    (in the returned pose's frame), the trunk bending forward at the pelvis, then the knees
    further, as far as they must to bring them within `reach` of the arms' length."""
    drop, ends = _LIBRARY[name]
    joints = rest_pose().copy()
    for side, sign in (("l_", 1.0), ("r_", -1.0)):                   # arms down, as standing_pose_2d
        elbow = joints[J[side + "shoulder"]] + (0.04 * sign, -0.26, 0.0)
        joints[J[side + "elbow"]], joints[J[side + "wrist"]] = elbow, elbow + (0.02 * sign, -0.24, 0.05)
    feet = {side: joints[J[side + "foot"]] - joints[J[side + "ankle"]] for side in ("l_", "r_")}
    standing = joints[J["pelvis"]].copy()
    turn = yaw_matrix(np.array(yaw))
    targets = {end: standing + ends[end] for end in ends}
    if hands is not None:   # into the unturned pose's frame
        targets.update(zip(("l_wrist", "r_wrist"), (np.asarray(hands, float) - standing) @ turn + standing))
    upper_body = [j for j in range(len(joints)) if j not in [J[n] for n in
                  ("l_knee", "r_knee", "l_ankle", "r_ankle", "l_foot", "r_foot")]]
    joints[upper_body] -= (0.0, drop, 0.0)
    if hands is not None:
        joints = _leaned_to_reach(joints, [targets["l_wrist"], targets["r_wrist"]], reach, upper_body)
    for end in ("l_ankle", "r_ankle", "l_wrist", "r_wrist"):
        root, mid = (J[n] for n in _LIMBS[end])
        target = targets.get(end, joints[J[end]])
        upper = np.linalg.norm(rest_pose()[mid] - rest_pose()[root])
        lower = np.linalg.norm(rest_pose()[J[end]] - rest_pose()[mid])
        pole = np.array([0.0, 0.0, 1.0]) if "ankle" in end else np.array([0.0, -0.5, -1.0])
        joints[mid], joints[J[end]] = two_bone_ik(joints[root], target, upper, lower, pole)
        if "ankle" in end:
            joints[J[end[:2] + "foot"]] = joints[J[end]] + feet[end[:2]]
    return (joints - standing) @ turn.T + standing


MOST_LEAN = np.deg2rad(90.0)   # the trunk bent level at most
MOST_SQUAT = 0.2               # m the pelvis goes further down than the pose's own drop, at most


def _above(joint: int) -> list[int]:
    """`joint` and every joint whose chain to the root passes through it (parents come first)."""
    out = [joint]
    for j in range(joint + 1, len(PARENTS)):
        if PARENTS[j] in out:
            out.append(j)
    return out


_TRUNK = _above(J["spine1"])


def _leaned_to_reach(joints: np.ndarray, wrists: list[np.ndarray], reach: float, upper_body: list[int]) -> np.ndarray:
    """The pose (22, 3, facing +Z) with its trunk bent forward about the pelvis, and then its
    upper body lowered, by the least (5 degree, 5 cm steps; at most MOST_LEAN, MOST_SQUAT) that
    puts both wrists' targets (3,) within `reach` arm's lengths of the shoulders; all of both
    where nothing does. The legs are left to be solved to the feet."""
    arm = np.linalg.norm(rest_pose()[J["l_elbow"]] - rest_pose()[J["l_shoulder"]]) \
        + np.linalg.norm(rest_pose()[J["l_wrist"]] - rest_pose()[J["l_elbow"]])
    for squat in np.arange(0.0, MOST_SQUAT + 1e-9, 0.05):
        low = joints.copy()
        low[upper_body] -= (0.0, squat, 0.0)
        pelvis = low[J["pelvis"]]
        for angle in np.arange(0.0, MOST_LEAN + 1e-9, np.deg2rad(5.0)):
            bent = low.copy()
            bent[_TRUNK] = (low[_TRUNK] - pelvis) @ pitch_matrix(np.array(angle)).T + pelvis
            shoulders = bent[[J["l_shoulder"], J["r_shoulder"]]]
            if all(np.linalg.norm(w - s) <= reach * arm + 1e-6 for w, s in zip(wrists, shoulders)):
                return bent
    return bent


def hands_placed(name: str) -> list[int]:
    """The wrists library pose `name` puts somewhere (a handshake's right one; both where it puts
    neither)."""
    return [J[w] for w in ("l_wrist", "r_wrist") if w in _LIBRARY[name][1]] or [J["l_wrist"], J["r_wrist"]]


def reach_of(name: str) -> np.ndarray:
    """Where library pose `name`'s placed hands reach, from its pelvis, on the ground plane: (3,)."""
    joints = library_pose(name)
    return (joints[hands_placed(name)].mean(0) - joints[J["pelvis"]]) * (1.0, 0.0, 1.0)


def library_pose_2d(name: str, camera: StoryboardCamera, yaw: float = 0.0, hands: np.ndarray | None = None,
                    reach: float = 1.0) -> np.ndarray:
    """library_pose seen through the camera, its pelvis where a standing figure's is: (22, 2)."""
    return camera.project(library_pose(name, yaw, hands, reach)) - camera.project(rest_pose()[:1])[0]
