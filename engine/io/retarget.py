"""Retargeting source skeletons onto the 22-joint SMPL body in our world frame.

A JointMap says where each of our 22 joints is on a source skeleton: one named node (End Sites are
"<parent>/End Site"), or the mean of several nodes ("midpoint" of two). It also carries `to_world`,
the rotation from the source's axes to ours (Y up, +Z forward, +X left). As JSON:

    {"name": "cmu_salsa",
     "to_world": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],            (optional, default identity)
     "joints": {"pelvis": "hip", "spine3": {"midpoint": ["chest", "neck"]},
                "l_foot": "lFoot/End Site", ...all 22...}}

The helpers below then put people on our ground at our size: one scale for everyone (from leg
length, so that the distance between partners stays real), a floor per person, and a check that
the result is upright and not mirrored.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..skeleton import FEET, JOINT_INDEX, JOINT_NAMES, rest_pose

_J = JOINT_INDEX
# Hip, knee, ankle of the left then the right leg (same order as skeleton.FEET).
LEGS = ((_J["l_hip"], _J["l_knee"], _J["l_ankle"]), (_J["r_hip"], _J["r_knee"], _J["r_ankle"]))
# The template's standing hip height above the ground (0.86 m; its feet stand on y = 0).
TEMPLATE_LEG_LENGTH = float(rest_pose()[_J["l_hip"], 1])


class RetargetError(ValueError):
    """A joint map that does not fit the data, or data that cannot be put in our world."""


@dataclass
class JointMap:
    name: str
    sources: dict[str, tuple[str, ...]]   # our joint name -> source node names to average
    to_world: np.ndarray = field(default_factory=lambda: np.eye(3))  # (3, 3) proper rotation

    def __post_init__(self):
        missing = [n for n in JOINT_NAMES if n not in self.sources]
        unknown = [n for n in self.sources if n not in JOINT_INDEX]
        if missing or unknown:
            raise RetargetError(f"joint map '{self.name}': missing joints {missing}, unknown joints {unknown}")
        for joint, nodes in self.sources.items():
            if not nodes or not all(isinstance(n, str) and n for n in nodes):
                raise RetargetError(f"joint map '{self.name}': joint '{joint}' needs one or more node names")
        self.to_world = np.asarray(self.to_world, dtype=np.float64)
        R = self.to_world
        if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise RetargetError(f"joint map '{self.name}': to_world must be a 3x3 rotation (det +1); "
                                "mirroring would swap left and right")

    @classmethod
    def from_dict(cls, d: dict) -> "JointMap":
        if not isinstance(d, dict) or not isinstance(d.get("joints"), dict):
            raise RetargetError("joint map must be an object with a 'joints' object")
        sources = {}
        for joint, spec in d["joints"].items():
            if isinstance(spec, str):
                sources[joint] = (spec,)
            elif isinstance(spec, dict) and set(spec) == {"midpoint"} and isinstance(spec["midpoint"], list):
                sources[joint] = tuple(spec["midpoint"])
            else:
                raise RetargetError(f"joint map: '{joint}' must be a node name or {{\"midpoint\": [a, b]}}")
        return cls(str(d.get("name", "")), sources, np.asarray(d.get("to_world", np.eye(3)), dtype=np.float64))

    def to_dict(self) -> dict:
        joints = {j: s[0] if len(s) == 1 else {"midpoint": list(s)} for j, s in self.sources.items()}
        return {"name": self.name, "to_world": self.to_world.tolist(), "joints": joints}

    @classmethod
    def load(cls, path: str | Path) -> "JointMap":
        try:
            d = json.loads(Path(path).read_text())
        except json.JSONDecodeError as e:
            raise RetargetError(f"{path}: not valid JSON ({e})") from None
        return cls.from_dict(d)

    def fits(self, node_names: list[str]) -> bool:
        """Whether a file with these nodes has every node the map reads."""
        return {n for nodes in self.sources.values() for n in nodes} <= set(node_names)

    def apply(self, node_names: list[str], positions: np.ndarray) -> np.ndarray:
        """Source node positions (F, J_src, 3) -> our joints (F, 22, 3), rotated into our axes."""
        index = {n: i for i, n in enumerate(node_names)}
        absent = sorted({n for nodes in self.sources.values() for n in nodes if n not in index})
        if absent:
            raise RetargetError(f"joint map '{self.name}': nodes not in the file: {', '.join(absent)}")
        out = np.stack([positions[:, [index[n] for n in self.sources[j]]].mean(axis=1) for j in JOINT_NAMES], 1)
        return out @ self.to_world.T


# The CMU root "hip" sits 2 cm below the hip joints; the SMPL pelvis sits 9 cm above them. The
# midpoint of hip and abdomen (rigid in the root's frame) is 7-8 cm above them, as in SMPL.
CMU_SALSA_MAP = JointMap.from_dict({
    "name": "cmu_salsa",
    "joints": {
        "pelvis": {"midpoint": ["hip", "abdomen"]}, "l_hip": "lThigh", "r_hip": "rThigh", "spine1": "abdomen",
        "l_knee": "lShin", "r_knee": "rShin", "spine2": "chest", "l_ankle": "lFoot", "r_ankle": "rFoot",
        "spine3": {"midpoint": ["chest", "neck"]}, "l_foot": "lFoot/End Site", "r_foot": "rFoot/End Site",
        "neck": "neck", "l_collar": "lCollar", "r_collar": "rCollar", "head": "head",
        "l_shoulder": "lShldr", "r_shoulder": "rShldr", "l_elbow": "lForeArm", "r_elbow": "rForeArm",
        "l_wrist": "lHand", "r_wrist": "rHand",
    },
})
# Our own 22-joint BVH export (bvh_export) read back as it is.
SMPL22_MAP = JointMap("smpl22", {n: (n,) for n in JOINT_NAMES})
BUILTIN_MAPS = {m.name: m for m in (CMU_SALSA_MAP, SMPL22_MAP)}


def load_joint_map(spec: str | Path) -> JointMap:
    """A built-in map by name (see BUILTIN_MAPS) or a JSON file path."""
    if str(spec) in BUILTIN_MAPS:
        return BUILTIN_MAPS[str(spec)]
    if not Path(spec).is_file():
        raise RetargetError(f"joint map '{spec}' is neither a built-in ({', '.join(BUILTIN_MAPS)}) nor a file")
    return JointMap.load(spec)


def leg_length(joints: np.ndarray, floor_percentile: float = 5.0) -> float:
    """Standing hip height of one person (F, 22, 3), in the data's units, averaged over both legs.

    Thigh + shin (median lengths) + the ankle's median height above the floor while that foot is
    the lower one. Bone lengths alone would miss how high the ankle sits (skeletons disagree on
    where the ankle joint is: 8 cm up in the SMPL template, 3-4 cm in the CMU files).
    """
    floor = estimate_floor(joints, floor_percentile)
    lowest = np.argmin(joints[:, list(FEET), 1], axis=1)
    lengths = []
    for side, (hip, knee, ankle) in enumerate(LEGS):
        thigh = np.linalg.norm(joints[:, knee] - joints[:, hip], axis=-1)
        shin = np.linalg.norm(joints[:, ankle] - joints[:, knee], axis=-1)
        stance = lowest == side
        ankle_height = joints[stance if stance.any() else slice(None), ankle, 1] - floor
        lengths.append(np.median(thigh) + np.median(shin) + np.median(ankle_height))
    return float(np.mean(lengths))


def body_scale(people: list[np.ndarray]) -> float:
    """One factor for all people (F, 22, 3) that makes their mean leg length the template's."""
    return TEMPLATE_LEG_LENGTH / float(np.mean([leg_length(p) for p in people]))


def estimate_floor(joints: np.ndarray, percentile: float = 5.0) -> float:
    """Floor height under one person (F, 22, 3): a low percentile of the lower foot per frame.

    Robust to a few frames of glitching markers (below) and to jumps (above), since in most
    frames one foot is on the ground.
    """
    lowest = joints[:, list(FEET), 1].min(axis=1)
    return float(np.percentile(lowest, percentile))


def check_orientation(joints: np.ndarray, who: str = "person") -> None:
    """Raise RetargetError unless one person (F, 22, 3) is upright and not mirrored in our axes.

    Upright: the head is above the pelvis in most frames. Not mirrored: with up = +Y and forward
    taken from the feet (ankle -> toe), the person's left (l_hip - r_hip) must be up x forward,
    which is what a right-handed Y-up frame with +Z forward and +X left gives.
    """
    up = joints[:, _J["head"], 1] - joints[:, _J["pelvis"], 1]
    if np.mean(up > 0) < 0.5:
        raise RetargetError(f"{who}: the head is below the pelvis in most frames; wrong up axis (to_world)?")
    forward = sum(joints[:, toe] - joints[:, ankle] for toe, ankle in
                  ((_J["l_foot"], _J["l_ankle"]), (_J["r_foot"], _J["r_ankle"])))
    left = joints[:, _J["l_hip"]] - joints[:, _J["r_hip"]]
    handed = np.cross(np.array([0.0, 1.0, 0.0]), forward)
    if np.mean(np.sum(handed * left, axis=-1) > 0) < 0.5:
        raise RetargetError(f"{who}: left and right are mirrored (left hip is on the right of the "
                            "facing direction); fix the joint map's l_/r_ entries or to_world")
