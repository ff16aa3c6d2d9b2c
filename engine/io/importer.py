"""From real motion to a MotionClip: the pipeline shared by the BVH, InterHuman and CORE4D importers.

Each format's reader brings our 22 joints per person in our axes (any unit). The shared steps
then (1) rescale everyone by one factor so that the mean leg length is the template's, (2) put
each person's floor at y = 0, (3) check that each person is upright and not mirrored, (4) solve
IK with per-person bone offsets (MotionClip.from_joints) and store the FK of that solution as the
clip's joints, so that positions, rotations and offsets agree exactly, (5) resample to the target
fps on the skeleton (root linear, rotations slerp) unless the reader already did (BVH resamples
in its own joint-angle domain). The report says how far the FK is from the imported joints.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..clip import MotionClip
from ..geometry.rotations import sixd_to_matrix
from ..skeleton import FEET, JOINT_INDEX, bone_lengths, forward_kinematics
from .bvh import BvhMotion, read_bvh
from .resample import resample_clip
from .retarget import BUILTIN_MAPS, CMU_SALSA_MAP, JointMap, RetargetError, body_scale, check_orientation, estimate_floor


@dataclass
class ImportConfig:
    fps: float = 20.0              # output frame rate
    rescale: bool = True           # match the template's leg length (one factor for everyone)
    floor: bool = True             # put each person's floor at y = 0
    floor_percentile: float = 5.0  # of the lower foot's height per frame


@dataclass
class Placement:
    joints: np.ndarray   # (F, H, 22, 3) scaled and floored, our axes, metres
    scale: float         # factor applied to the source coordinates
    floors: np.ndarray   # (H,) floor height of each person after scaling, subtracted from y


@dataclass
class ImportReport:
    source_fps: float
    scale: float
    floors: np.ndarray             # (H,) metres, see Placement
    fk_error: float                # max over frames, people, joints of |FK(IK) - imported| (m)
    bone_drift: float              # max over people and bones of (max - min) length over frames (m)
    pelvis_height: np.ndarray      # (H,) mean pelvis height above the floor (m)
    foot_height: np.ndarray        # (H, 3) 5th, 50th, 95th percentile of the lower foot's height (m)

    def summary(self) -> str:
        pelvis = ", ".join(f"{v:.2f}" for v in self.pelvis_height)
        feet = ", ".join(f"{v[1] * 100:.1f}" for v in self.foot_height)
        return (f"scale {self.scale:.3f}, pelvis {pelvis} m, median lower foot {feet} cm, "
                f"FK error {self.fk_error * 1000:.2f} mm, bone drift {self.bone_drift * 1000:.3f} mm")


def place_people(joints: np.ndarray, cfg: ImportConfig) -> Placement:
    """joints: (F, H, 22, 3) in our axes -> Placement (scaled, floored, orientation checked)."""
    people = [joints[:, h] for h in range(joints.shape[1])]
    scale = body_scale(people) if cfg.rescale else 1.0
    joints = joints * scale
    floors = np.array([estimate_floor(joints[:, h], cfg.floor_percentile) if cfg.floor else 0.0
                       for h in range(joints.shape[1])])
    joints[..., 1] -= floors[None, :, None]
    for h in range(joints.shape[1]):
        check_orientation(joints[:, h], who=f"person {h + 1}")
    return Placement(joints, scale, floors)


def fit_clip(joints: np.ndarray, fps: float, **clip_fields) -> tuple[MotionClip, float]:
    """IK-fit joints (N, H, 22, 3); returns the clip (joints replaced by FK) and max FK error (m)."""
    clip = MotionClip.from_joints(joints, fps, **clip_fields)
    fk = np.stack([forward_kinematics(joints[:, h, 0], sixd_to_matrix(clip.rot6d[:, h].astype(np.float64)),
                                      clip.bone_offsets[h]) for h in range(clip.num_humans)], 1)
    clip.joints = fk.astype(np.float32)
    return clip, float(np.max(np.linalg.norm(fk - joints, axis=-1)))


def finish_clip(placed: Placement, data_fps: float, cfg: ImportConfig, source_fps: float,
                **clip_fields) -> tuple[MotionClip, ImportReport]:
    """Fit placed people at data_fps, resample to cfg.fps on the skeleton, report.

    clip_fields go to MotionClip (scenario, objects at data_fps...).
    """
    clip, fk_error = fit_clip(placed.joints, data_fps, **clip_fields)
    if not np.isclose(data_fps, cfg.fps):
        clip = resample_clip(clip, cfg.fps)
    return clip, import_report(clip, source_fps, placed, fk_error)


def people_to_clip(joints: np.ndarray, cfg: ImportConfig, data_fps: float, source_fps: float | None = None,
                   **clip_fields) -> tuple[MotionClip, ImportReport]:
    """joints: (F, H, 22, 3) in our axes at data_fps -> (clip at cfg.fps, report).

    Positions-only data is fitted at its own rate and then resampled on the skeleton (rotations
    by slerp), so bones stay rigid. source_fps (default data_fps) is only reported.
    """
    placed = place_people(joints, cfg)
    return finish_clip(placed, data_fps, cfg, source_fps or data_fps, **clip_fields)


def import_report(clip: MotionClip, source_fps: float, placed: Placement, fk_error: float) -> ImportReport:
    j = clip.joints.astype(np.float64)
    lengths = bone_lengths(j)                                        # (N, H, 22)
    lowest_foot = j[:, :, list(FEET), 1].min(axis=2)                 # (N, H)
    return ImportReport(
        source_fps=source_fps, scale=placed.scale, floors=placed.floors, fk_error=fk_error,
        bone_drift=float(np.max(lengths.max(axis=0) - lengths.min(axis=0))),
        pelvis_height=j[:, :, JOINT_INDEX["pelvis"], 1].mean(axis=0),
        foot_height=np.percentile(lowest_foot, [5, 50, 95], axis=0).T,
    )


def bvh_people(motions: list[BvhMotion], joint_map: JointMap, names: list[str],
               fps: float) -> tuple[np.ndarray, float]:
    """Synchronized BVH takes -> (our joints (M, H, 22, 3) in our axes at fps, source fps)."""
    first = motions[0]
    for m, name in zip(motions, names):
        if m.num_frames != first.num_frames or not np.isclose(m.frame_time, first.frame_time):
            raise RetargetError(f"{name}: {m.num_frames} frames at {m.frame_time:g} s does not match "
                                f"{names[0]}: {first.num_frames} frames at {first.frame_time:g} s")
        if m.num_frames < 2:
            raise RetargetError(f"{name}: a motion needs at least 2 frames, found {m.num_frames}")
    joints = np.stack([joint_map.apply(m.names, m.global_positions(fps)) for m in motions], axis=1)
    return joints, first.fps


def import_bvh(paths: list[str | Path], cfg: ImportConfig | None = None,
               joint_map: JointMap | None = None) -> tuple[MotionClip, ImportReport]:
    """One BVH file per person (a synchronized take sharing one world frame) -> (clip, report).
    Without a joint map, the built-in one whose nodes the first file has (our own export's, or
    CMU's; else CMU's, and the error names the nodes it lacks)."""
    cfg = cfg or ImportConfig()
    if not paths:
        raise RetargetError("import_bvh needs at least one BVH file")
    names = [str(p) for p in paths]
    motions = [read_bvh(p) for p in paths]
    if joint_map is None:
        joint_map = next((m for m in BUILTIN_MAPS.values() if m.fits(motions[0].names)), CMU_SALSA_MAP)
    # Resampled in the BVH's own joint-angle domain, so the people arrive at cfg.fps already.
    joints, source_fps = bvh_people(motions, joint_map, names, cfg.fps)
    scenario = "bvh:" + "+".join(Path(p).stem for p in paths)
    return people_to_clip(joints, cfg, cfg.fps, source_fps, scenario=scenario)
