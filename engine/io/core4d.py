"""Loader for CORE4D-Real (Liu, Zhang et al. 2024) human-object-human sequences in its released layout.

    <root>/human_object_motions/<date>/<sequence>/person1_poses.npz, person2_poses.npz
    <root>/human_object_motions/<date>/<sequence>/object_poses_<object name>.npy   (N, 4, 4)
    <root>/object_models/<category>/<object name>_m.obj                           metres

A person file is np.savez of one dict (key "arr_0", a pickle: read by engine.io.safe_pickle, which
rebuilds arrays and plain containers only and runs no code) holding SMPL-X parameters and "joints" (N, 127, 3): the first 22 are
the SMPL body joints in our order. An object pose is the 4x4 world transform of its canonical
mesh. We use joint positions (rotations re-solved on our skeleton) and object poses; the mesh
gives the object's size and its category folder its type.

The dataset documentation states neither the world's up axis nor the frame rate: the up axis
is found from the data (the axis from pelvis to head) and turned into +Y with a proper rotation
(check_orientation then catches a mirrored world); the frame rate is a setting.
"""
from __future__ import annotations

import pickle
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..clip import MotionClip
from ..geometry.rotations import matrix_to_quat, rotation_between
from ..skeleton import JOINT_INDEX, NUM_JOINTS
from .importer import ImportConfig, ImportReport, finish_clip, place_people
from .retarget import RetargetError
from .safe_pickle import load_pickled_entry


@dataclass
class Core4dConfig:
    source_fps: float = 15.0  # assumed: not stated by the dataset documentation; set it for your copy
    import_config: ImportConfig = field(default_factory=lambda: ImportConfig(fps=20.0, rescale=False))


@dataclass
class Core4dSample:
    name: str                  # "<date>/<sequence>"
    clip: MotionClip           # two people and the sequence's objects, our world, requested fps
    object_names: list[str]    # (O,) in clip order
    report: ImportReport


def list_core4d(root: str | Path) -> list[str]:
    """Sequence names "<date>/<sequence>" that have both person files."""
    base = Path(root) / "human_object_motions"
    return sorted(f"{p.parent.parent.name}/{p.parent.name}" for p in base.glob("*/*/person1_poses.npz")
                  if (p.parent / "person2_poses.npz").is_file())


def _person_joints(path: Path) -> np.ndarray:
    """(N, 22, 3) body joints from one CORE4D person file, in the file's world frame."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: missing CORE4D person file")
    try:
        params = load_pickled_entry(path, "arr_0")
    except KeyError:
        raise RetargetError(f"{path}: expected an 'arr_0' entry holding the pose dict") from None
    except (pickle.UnpicklingError, zipfile.BadZipFile, ValueError, EOFError) as e:
        raise RetargetError(f"{path}: not a CORE4D person file ({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
    joints = np.asarray(params.get("joints") if isinstance(params, dict) else None)
    if joints.ndim != 3 or joints.shape[1] < NUM_JOINTS or joints.shape[2] != 3 or joints.shape[0] < 2:
        raise RetargetError(f"{path}: expected 'joints' of shape (N >= 2, >= 22, 3), got {joints.shape}")
    return joints[:, :NUM_JOINTS].astype(np.float64)


def up_to_ours(joints: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking the data's up axis (pelvis -> head, nearest coordinate axis) to +Y."""
    up = np.mean(joints[..., JOINT_INDEX["head"], :] - joints[..., JOINT_INDEX["pelvis"], :],
                 axis=tuple(range(joints.ndim - 2)))
    axis = np.zeros(3)
    k = int(np.argmax(np.abs(up)))
    axis[k] = np.sign(up[k])
    return rotation_between(axis, np.array([0.0, 1.0, 0.0]))


def _mesh_extent(path: Path) -> np.ndarray | None:
    """Bounding-box size (3,) of an OBJ's vertices, or None if the file is absent or empty."""
    if not path.is_file():
        return None
    verts = [line.split()[1:4] for line in path.read_text(errors="replace").splitlines() if line.startswith("v ")]
    if not verts:
        return None
    v = np.asarray(verts, dtype=np.float64)
    return v.max(axis=0) - v.min(axis=0)


def _object_model(root: Path, name: str) -> tuple[str, np.ndarray]:
    """(type, size (3,)) of an object from its model file, ("mesh", zeros) if not found."""
    for path in sorted((root / "object_models").glob(f"*/{name}_m.obj")):
        extent = _mesh_extent(path)
        if extent is not None:
            return path.parent.name, extent
    return "mesh", np.zeros(3)


def load_core4d(root: str | Path, name: str, cfg: Core4dConfig | None = None) -> Core4dSample:
    """One CORE4D-Real sequence ("<date>/<sequence>") as a MotionClip with its objects."""
    cfg = cfg or Core4dConfig()
    root = Path(root)
    seq = root / "human_object_motions" / name
    people = [_person_joints(seq / f"{who}_poses.npz") for who in ("person1", "person2")]
    n = people[0].shape[0]
    object_files = sorted(seq.glob("object_poses_*.npy"))
    poses = [np.load(p, allow_pickle=False) for p in object_files]
    for path, arr in zip([seq / "person2_poses.npz"] + object_files, [people[1]] + poses):
        if arr.shape[0] != n:
            raise RetargetError(f"{path}: {arr.shape[0]} frames, person1 has {n}")
    for path, pose in zip(object_files, poses):
        if pose.shape[1:] != (4, 4):
            raise RetargetError(f"{path}: expected object poses of shape (N, 4, 4), got {pose.shape}")

    to_ours = up_to_ours(np.stack(people, 1))
    joints = np.stack(people, axis=1) @ to_ours.T                              # (N, 2, 22, 3)
    icfg = cfg.import_config
    placed = place_people(joints, icfg)
    clip_fields = {"scenario": f"core4d:{name}"}
    names = [p.stem[len("object_poses_"):] for p in object_files]
    if poses:
        pose = np.stack(poses, axis=1).astype(np.float64)                      # (N, O, 4, 4)
        # Same world change as the people: rotate, scale, lower by the mean floor.
        trans = pose[..., :3, 3] @ to_ours.T * placed.scale
        trans[..., 1] -= placed.floors.mean()
        models = [_object_model(root, o) for o in names]
        clip_fields.update(obj_pose=np.concatenate([trans, matrix_to_quat(to_ours @ pose[..., :3, :3])], -1),
                           obj_type=np.array([t for t, _ in models]),
                           obj_size=np.stack([s for _, s in models]) * placed.scale)
    clip, report = finish_clip(placed, cfg.source_fps, icfg, cfg.source_fps, **clip_fields)
    return Core4dSample(name, clip, names, report)
