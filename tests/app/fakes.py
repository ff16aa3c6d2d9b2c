"""Stand-ins for the sampler and a sample storyboard, shared by the app tests and screenshots."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from app.document import new_storyboard
from app.generation import GenerationSettings
from engine.clip import MotionClip
from engine.geometry.rotations import matrix_to_6d
from engine.objects import ObjectSpec
from engine.poses import standing_pose_2d
from engine.sampling.events import GenerationResult, StepEvent
from engine.skeleton import JOINT_INDEX, NUM_JOINTS, rest_pose
from engine.storyboard import Contact, Keypose, ObjectKey, ObjectPath, SceneObject, Storyboard, Trajectory


def walking_clip(length: int, fps: float, progress: float = 1.0) -> MotionClip:
    """Two rest-pose people walking towards +X side by side, 1.2 m apart, a box between them;
    `progress` in [0, 1] blends from a jumble (noise) to the clean motion, like a sampler."""
    rest = rest_pose()
    t = np.linspace(0.0, 1.0, length)[:, None, None, None]
    starts = np.array([[-1.0, 0.0, -0.6], [-1.0, 0.0, 0.6]])[None, :, None, :]
    joints = rest[None, None] + starts + t * np.array([2.0, 0.0, 0.0])
    swing = 0.25 * np.sin(2 * np.pi * 2 * t[:, :, 0, 0])  # (N, 1)
    for side, sign in (("l_", 1), ("r_", -1)):
        for j in ("ankle", "foot"):
            joints[:, :, JOINT_INDEX[side + j], 0] += sign * swing
    noise = np.random.default_rng(0).normal(0, 0.15, joints.shape)
    joints = joints + (1 - progress) * noise
    rot6d = np.broadcast_to(matrix_to_6d(np.eye(3)), (length, 2, NUM_JOINTS, 6))
    pos = np.zeros((length, 1, 7))
    pos[:, 0, :3] = (joints[:, 0, 0] + joints[:, 1, 0]) / 2 * np.array([1, 0, 1])
    pos[:, 0, 3] = 1.0
    pos[:, 0, 1] = 0.55
    return MotionClip(fps=fps, joints=joints, rot6d=rot6d, obj_pose=pos, obj_type=np.array(["box"]),
                      obj_size=np.array([[0.45, 0.35, 0.35]]), phase=phase_schedule(length, progress))


def phase_schedule(length: int, progress: float) -> np.ndarray:
    """(N, 3) occupancy: approach, then contact, then carry, sharpening as progress grows."""
    f = np.arange(length) / max(length - 1, 1)
    sharp = 4 + 40 * progress
    carry = 1 / (1 + np.exp(-sharp * (f - 0.55)))
    reach = 1 / (1 + np.exp(-sharp * (f - 0.3)))
    out = np.stack([1 - reach, reach * (1 - carry), carry], axis=-1)
    return out / out.sum(axis=-1, keepdims=True)


@dataclass
class FakeSampler:
    """A generator factory shaped like app.generation.start_generation, with knobs for tests."""
    delay_s: float = 0.0
    fail_at: int | None = None
    closed: list = field(default_factory=list)     # True once a stream was closed early
    yielded: list = field(default_factory=list)    # step indices in the order they were yielded
    notes: list = field(default_factory=list)      # the result's notes (what finishing could not do)

    def __call__(self, storyboard: Storyboard, settings: GenerationSettings):
        started = time.perf_counter()
        first = None
        try:
            for step in range(settings.steps):
                if self.delay_s:
                    time.sleep(self.delay_s)
                if step == self.fail_at:
                    raise RuntimeError("the model ran out of patience")
                progress = (step + 1) / settings.steps
                clip = walking_clip(storyboard.length, storyboard.fps, progress)
                first = first or time.perf_counter() - started
                self.yielded.append(step)
                yield StepEvent(step=step, num_steps=settings.steps, t=1 - progress,
                                latent=np.zeros((settings.variations, 4, 3, 8), np.float32),
                                decode=lambda clip=clip: clip, phase=clip.phase, energies={"keyframe": 1 / (step + 1)})
        except GeneratorExit:
            self.closed.append(True)
            raise
        clips = [walking_clip(storyboard.length, storyboard.fps) for _ in range(settings.variations)]
        return GenerationResult(clips, time.perf_counter() - started, first or 0.0, settings.steps,
                                notes=list(self.notes))



def sample_storyboard() -> Storyboard:
    """Two people carry a box along a path: keyposes, pelvis paths, the box and contacts."""
    sb = new_storyboard()
    cam = sb.camera
    figure = standing_pose_2d(cam)
    for agent, z in (("A", -0.6), ("B", 0.6)):
        for frame, x in ((0, -1.0), (60, 0.0), (119, 1.0)):
            pelvis = cam.project(np.array([x, 0.95, z]))
            points = figure + pelvis
            if frame == 60:  # reaching for the box
                for side in ("l_", "r_"):
                    points[JOINT_INDEX[side + "wrist"], 1] += 0.25
                    points[JOINT_INDEX[side + "elbow"], 1] += 0.1
            sb.keyposes.append(Keypose(agent, frame, points, np.ones(NUM_JOINTS, bool)))
        path = cam.project(np.stack([np.linspace(-1, 1, 12), np.full(12, 0.95), z + 0.1 * np.sin(np.linspace(0, 3, 12))], -1))
        sb.trajectories.append(Trajectory(agent, "pelvis", 0, 119, path))
    sb.objects.append(SceneObject("box1", ObjectSpec("box")))
    centre = cam.project(np.array([0.0, 0.55, 0.0]))
    outline = centre + np.array([[-0.24, -0.2], [0.24, -0.2], [0.24, 0.2], [-0.24, 0.2]])
    sb.object_keys.append(ObjectKey("box1", 60, outline))
    box_path = cam.project(np.stack([np.linspace(0, 1, 6), np.full(6, 0.55), np.zeros(6)], -1))
    sb.object_paths.append(ObjectPath("box1", 60, 119, box_path))
    sb.contacts.append(Contact("A", "right", 60, 119, object="box1", anchor=0))
    sb.contacts.append(Contact("B", "left", 60, 119, object="box1", anchor=1))
    sb.validate()
    return sb
