"""A small built-in scene: two people carrying a box sideways, with a storyboard that asks for
it. Used by the renderer's warm-up, the renderer tests and as a quick look at the renderer.
"""
from __future__ import annotations

import numpy as np

from ..body import hand_centres
from ..camera import StoryboardCamera
from ..clip import MotionClip
from ..geometry.rotations import matrix_to_6d, rotation_between
from ..objects import ObjectSpec
from ..skeleton import JOINT_INDEX, NUM_JOINTS, REST_PELVIS_HEIGHT, forward_kinematics
from ..storyboard import Agent, Keypose, SceneObject, Storyboard, Trajectory
from .scene import SceneState, scene_from_clip

J = JOINT_INDEX
BOX = ObjectSpec("box")


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def carrying_pose(root: np.ndarray, facing: float, reach: float = 1.0) -> np.ndarray:
    """Joints (22, 3) of a person at `root` facing yaw `facing` (0 = +Z), arms reaching forward
    and down by `reach` (0 = rest T-pose arms, 1 = holding a box at hip height)."""
    rot = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    rot[J["pelvis"]] = _yaw(facing)
    for side, sign in (("l", 1.0), ("r", -1.0)):
        forward_down = np.array([sign * 0.12, -0.75, 0.65])
        arm = (1 - reach) * np.array([sign, 0.0, 0.0]) + reach * forward_down / np.linalg.norm(forward_down)
        rot[J[f"{side}_shoulder"]] = rotation_between(np.array([sign, 0.0, 0.0]), arm)
        rot[J[f"{side}_elbow"]] = rotation_between(np.array([sign, 0.0, 0.0]),
                                                   np.array([sign, 0.25 * reach, 0.3 * reach + 1e-3 * (1 - reach)]))
    return forward_kinematics(np.asarray(root, float), rot)


def carry_clip(frames: int = 40, fps: float = 20.0) -> MotionClip:
    """Two people face each other across a box and carry it 1.5 m along +Z while it bobs."""
    t = np.linspace(0.0, 1.0, frames)
    z = 1.5 * (3 * t ** 2 - 2 * t ** 3) - 0.75   # ease in and out
    bob = 0.02 * np.sin(t * 6 * np.pi)
    joints = np.empty((frames, 2, NUM_JOINTS, 3), np.float32)
    for n in range(frames):
        pelvis_y = REST_PELVIS_HEIGHT - 0.02 + bob[n]
        joints[n, 0] = carrying_pose((-0.62, pelvis_y, z[n]), np.pi / 2)
        joints[n, 1] = carrying_pose((0.62, pelvis_y, z[n]), -np.pi / 2)
    # The box hangs between the four hands.
    pose = np.zeros((frames, 1, 7), np.float32)
    pose[:, 0, :3] = hand_centres(joints).mean(axis=(1, 2)) - [0.0, BOX.size[1] / 2, 0.0]
    pose[:, 0, 3] = 1.0
    rot = np.broadcast_to(np.eye(3), (frames, 2, NUM_JOINTS, 3, 3))
    return MotionClip(fps=fps, joints=joints, rot6d=matrix_to_6d(rot), obj_pose=pose,
                      obj_type=np.array(["box"]), obj_size=np.array([BOX.size]),
                      contact=np.ones((frames, 2, 2), np.float32), scenario="example carry")


def carry_storyboard(clip: MotionClip) -> Storyboard:
    """A storyboard the clip roughly satisfies: keyposes at both ends and a wavy pelvis path."""
    cam = StoryboardCamera()
    sb = Storyboard(fps=clip.fps, length=clip.num_frames, camera=cam,
                    agents=[Agent("a", "A", "#e4572e"), Agent("b", "B", "#2e86ab")],
                    objects=[SceneObject("box", BOX)])
    for frame in (0, clip.num_frames - 1):
        for h, agent in enumerate(("a", "b")):
            sb.keyposes.append(Keypose(agent, frame, cam.project(clip.joints[frame, h]), np.ones(NUM_JOINTS, bool)))
    pelvis = cam.project(clip.joints[:, 0, J["pelvis"]])
    wobble = 0.06 * np.sin(np.linspace(0, 2 * np.pi, len(pelvis)))[:, None] * np.array([1.0, 0.0])
    sb.trajectories.append(Trajectory("a", "pelvis", 0, clip.num_frames - 1, pelvis + wobble))
    return sb


def warm_up_scenes() -> list[SceneState]:
    """The example in steps of growing content: ground and sky; the people and their shadows;
    keyframe ghosts; paths and contact glows; the box. Drawing them in turn compiles every
    shader, a few per step; only the last needs an object mesh (and so trimesh)."""
    clip = carry_clip(4)
    full = scene_from_clip(clip, 1, carry_storyboard(clip))
    people = SceneState(people=full.people, colors=full.colors)
    ghosts = SceneState(people=full.people, colors=full.colors, ghosts=full.ghosts)
    overlays = scene_from_clip(clip, 1, carry_storyboard(clip))
    overlays.objects = []
    return [SceneState(), people, ghosts, overlays, full]
