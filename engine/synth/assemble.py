"""Plan -> MotionClip: pose each person, label phases, attach the object.

Phase labels (one-hot over clip.PHASES) follow the plan's events: `contact` inside a window
around a grasp, release or hand-off; otherwise `carry` while any hand holds (the object, or
the other person's hand); otherwise `approach` (walking up, waiting, withdrawing).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..clip import PHASES, MotionClip
from ..geometry.rotations import matrix_to_6d
from .body import BodyConfig, pose_person
from .gait import GaitConfig, plan_footwork
from .props import world_anchors
from .scenarios import ScenarioConfig, ScenePlan, build_plan


@dataclass
class SynthConfig:
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    gait: GaitConfig = field(default_factory=GaitConfig)
    body: BodyConfig = field(default_factory=BodyConfig)


def phase_labels(times: np.ndarray, windows: list[tuple[float, float]], holding: np.ndarray) -> np.ndarray:
    """times (N,), windows [(start, stop)] in seconds, holding (N,) bool -> (N, 3) one-hot."""
    in_window = np.zeros(len(times), bool)
    for start, stop in windows:
        in_window |= (times >= start) & (times <= stop)
    state = np.where(in_window, PHASES.index("contact"), np.where(holding, PHASES.index("carry"),
                                                                  PHASES.index("approach")))
    return np.eye(len(PHASES))[state]


def plan_to_clip(plan: ScenePlan, fps: float, config: SynthConfig) -> MotionClip:
    joints, rots = [], []
    for person in plan.people:
        feet = plan_footwork(person.ground, person.yaw, person.body.stance(config.body),
                             person.body.scale, config.gait)
        j, r = pose_person(person.body, person.ground, person.yaw, feet, person.hand_target,
                           person.hand_weight, fps, config.body)
        joints.append(j)
        rots.append(r)
    times = np.arange(len(plan.obj_pose)) / fps
    contact = np.stack([p.contact for p in plan.people], axis=1)
    return MotionClip(
        fps=fps, joints=np.stack(joints, 1), rot6d=matrix_to_6d(np.stack(rots, 1)),
        obj_pose=plan.obj_pose[:, None], obj_anchors=world_anchors(plan.spec, plan.obj_pose)[:, None],
        obj_type=np.array([plan.spec.type]), obj_size=np.array([plan.spec.size]),
        bone_offsets=np.stack([p.body.offsets for p in plan.people]),
        phase=phase_labels(times, plan.windows, contact.any(axis=(1, 2))),
        contact=contact.astype(np.float32), scenario=plan.scenario)


def synthesize(scenario: str, seed: int, fps: float = 20, seconds: float = 6.0,
               config: SynthConfig | None = None) -> MotionClip:
    """One procedural two-person scene as a MotionClip; the same arguments give the same arrays.

    Shapes: joints (N, 2, 22, 3), rot6d (N, 2, 22, 6), obj_pose (N, 1, 7), obj_anchors (N, 1, 4, 3),
    phase (N, 3), contact (N, 2, 2), with N = round(seconds * fps).
    """
    config = config or SynthConfig()
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    n = int(round(seconds * fps))
    # Seed from (seed, scenario) so each scenario draws its own stream.
    rng = np.random.default_rng([int(seed), sum(map(ord, scenario)) if isinstance(scenario, str) else 0])
    plan = build_plan(scenario, rng, np.arange(n) / fps, config.scenario)
    return plan_to_clip(plan, fps, config)
