"""Loader for the InterHuman dataset (InterGen, Liang et al. 2024) in its released file layout.

    <root>/motions_processed/person1/<name>.npy   (T, D) float, one row per frame at 30 fps
    <root>/motions_processed/person2/<name>.npy   same T as person1
    <root>/annots/<name>.txt                      text descriptions, one per line (usually 3)
    <root>/split/{train,val,test}.txt             motion names, one per line (also accepted at <root>)
    <root>/ignore_list.txt                        optional: names to skip

Columns of a motion row (as InterGen's loader reads them): [0:186] positions of 62 joints, the 22
SMPL body joints first (our order), in metres in a Z-up world; [186:312] 6D rotations of the 21
non-root body joints, then hand rotations. We read the 22 body positions only and solve rotations
on our skeleton (MotionClip.from_joints), which avoids depending on their rotation convention.
Their Z-up frame becomes ours by the rotation (x, y, z) -> (x, z, -y), as InterGen does itself.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..clip import MotionClip
from ..skeleton import NUM_JOINTS
from .importer import ImportConfig, ImportReport, people_to_clip
from .retarget import RetargetError

INTERHUMAN_FPS = 30.0
ZUP_TO_OURS = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
SPLITS = ("train", "val", "test")


@dataclass
class InterHumanSample:
    name: str
    clip: MotionClip           # two people, in our world and at the requested fps
    texts: list[str]           # the annotations; empty if the file is missing
    report: ImportReport


@dataclass
class InterHumanConfig:
    # Real SMPL bodies already have real sizes: keep them (no leg-length rescale).
    import_config: ImportConfig = field(default_factory=lambda: ImportConfig(fps=20.0, rescale=False))


def list_interhuman(root: str | Path, split: str | None = None) -> list[str]:
    """Motion names under `root`: those of a split file, or every person1 motion; ignore list removed."""
    root = Path(root)
    if split is not None:
        if split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS}, got '{split}'")
        path = next((p for p in (root / "split" / f"{split}.txt", root / f"{split}.txt") if p.is_file()), None)
        if path is None:
            raise FileNotFoundError(f"{root}: no split file for '{split}' (split/{split}.txt or {split}.txt)")
        names = [line.strip() for line in path.read_text().splitlines() if line.strip()]
    else:
        names = sorted(p.stem for p in (root / "motions_processed" / "person1").glob("*.npy"))
    ignore = root / "ignore_list.txt"
    skip = {line.strip() for line in ignore.read_text().splitlines()} if ignore.is_file() else set()
    return [n for n in names if n not in skip]


def _body_positions(path: Path) -> np.ndarray:
    """(T, 22, 3) body joint positions of one person's motion file, in the file's Z-up frame."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: missing InterHuman motion file")
    motion = np.load(path, allow_pickle=False)
    if motion.ndim != 2 or motion.shape[1] < NUM_JOINTS * 3 or motion.shape[0] < 2:
        raise RetargetError(f"{path}: expected a (T >= 2, D >= 66) motion array, got {motion.shape}")
    return motion[:, :NUM_JOINTS * 3].reshape(-1, NUM_JOINTS, 3).astype(np.float64)


def load_interhuman(root: str | Path, name: str, cfg: InterHumanConfig | None = None) -> InterHumanSample:
    """One InterHuman motion (both people) as a MotionClip in our conventions."""
    cfg = cfg or InterHumanConfig()
    root = Path(root)
    people = [_body_positions(root / "motions_processed" / who / f"{name}.npy") for who in ("person1", "person2")]
    if people[0].shape[0] != people[1].shape[0]:
        raise RetargetError(f"{root}: motion {name}: person1 has {people[0].shape[0]} frames, "
                            f"person2 {people[1].shape[0]}")
    joints = np.stack(people, axis=1) @ ZUP_TO_OURS.T                         # (T, 2, 22, 3)
    clip, report = people_to_clip(joints, cfg.import_config, INTERHUMAN_FPS, scenario=f"interhuman:{name}")
    annots = root / "annots" / f"{name}.txt"
    texts = [t.strip() for t in annots.read_text().splitlines() if t.strip()] if annots.is_file() else []
    return InterHumanSample(name, clip, texts, report)
