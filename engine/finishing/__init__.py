"""Finishing: the generated motion made to honour the storyboard's hard constraints.

The guided sampler brings the motion near the sketch; finishing, as an animator's clean-up pass
would, makes it exact where a 2D sketch and physics say what is right, by small kinematic edits
that keep each person's bone lengths:

0. the motion retimed to the keys' timing: still through a key's hold, easing into and out of
   keys marked so (timing.py);
1. one skeleton per person (bone offsets fitted to the generated joints; the decoder predicts
   joints freely, so bones stretch a little from frame to frame), its pelvis never turning half
   round in a frame (turns.py), its feet staying where they were while it turns;
2. keyposes, by motion warping (warp.py), and pelvis strokes walked on time (paths.py);
3. feet standing on the ground, planted while in stance (where a keypose in the stance has the
   foot), stepping between plants (one foot at a time: walk.py; a foot dragged along the floor
   while the other stands lifted into a step), the body lowering where it
   stands too tall for its planted legs (feet.py);
4. the object as a rigid body that moves only in the hands that hold it, resting clear of the
   people's legs otherwise (held.py), and the arms reaching its grips (or the partner's hand)
   over every contact span (contacts.py); a holder the grip is beyond arm's reach of steps
   towards it first, before the feet are planted (held.py), and a holder the grips are below the
   reach of crouches and leans to them (crouch.py): a box let go of is put down, not dropped;
   for an object the storyboard gives
   no contact, the holds are the generated motion's (inferred.py); hands out of a hold and feet
   pushed out of the objects they sink into (clearance.py), knees and elbows swivelled out of them
   (swivel.py);
5. knees and elbows that the stages above left popping smoothed on the circles that keep their
   bone lengths (limbs.py);
6. the whole body smoothed where it still pops, what the stages above made exact held
   (steady.py); hands, feet, knees and elbows that this puts back into an object pushed out again
   and smoothed once more with the pushed joints held, and knees and elbows that it leaves popping
   between their ends smoothed once more (limbs.py), never deeper into an object.
Joints and local rotations stay consistent: FK(root, rot6d, bone_offsets) == joints.
A preview is finished without the clean-up (FinishConfig.polish): the step and crouch of 4, the
elbow and knee swivels, the hands pushed out of objects and the smoothing of 5 and 6.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Callable

import numpy as np

from ..clip import MotionClip
from ..geometry.rotations import matrix_to_6d
from ..skeleton import FEET, fit_offsets, forward_kinematics, inverse_kinematics
from ..storyboard import Storyboard
from .clearance import clear_feet, clear_hands
from .contacts import ContactConfig, object_anchors, reach_contacts
from .crouch import crouch_to_grips
from .feet import FeetConfig, lock_feet, reach_with_legs, settle_on_ground
from .held import hold_object, step_within_reach
from .inferred import InferConfig, with_generated_contacts
from .keys import key_frames
from .limbs import LimbConfig, steady_limbs, steady_rotations
from .steady import SteadyConfig, frame_pops, steady_body
from .swivel import clear_elbows, clear_knees
from .timing import retime_to_keys, with_hold_ends
from .turns import spread_flips
from .paths import PathConfig, follow_paths
from .warp import BODY_PARTS, WarpConfig, scale_per_bone, sketched_scales, warp_to_keyposes

TUNED_FPS = 20.0   # the configs' durations (their DURATIONS fields) are frames at this rate


@dataclass
class FinishConfig:
    keyposes: bool = True
    paths: bool = True
    contacts: bool = True
    feet: bool = True
    warp: WarpConfig = field(default_factory=WarpConfig)
    path: PathConfig = field(default_factory=PathConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)
    inferred: InferConfig = field(default_factory=InferConfig)
    foot: FeetConfig = field(default_factory=FeetConfig)
    limbs: LimbConfig = field(default_factory=LimbConfig)
    # The pass after the steadying, at half the tolerance (guarded by the pops: 40 fresh
    # artist-style storyboards within 5 cm 42 -> 48%; at 2 cm, 42%).
    last_limbs: LimbConfig = field(default_factory=lambda: LimbConfig(tolerance=0.01))
    steady: SteadyConfig = field(default_factory=SteadyConfig)
    # The clean-up an animator does without while dragging, 60% of the finishing's time: the step
    # and crouch to grips out of reach, elbows and knees swivelled off the objects, hands pushed
    # out and the smoothing of pops (limbs.py, steady.py). A preview leaves it out (sampler_config); keys,
    # paths, planted feet and the object in the hands stay exact.
    polish: bool = True


def consistent_skeleton(joints: np.ndarray, storyboard: Storyboard | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Joints (N, H, 22, 3) -> (the same motion on one rigid skeleton per person, its bone
    offsets (H, 22, 3)). With a storyboard, body parts its keyposes show larger are scaled up
    (the pelvis height with the legs): the decoder draws bodies towards the average size."""
    offsets = fit_offsets(joints, iterations=1)   # (H, 22, 3); one refit of the branching bones is enough here
    people = range(joints.shape[1])
    scales = [sketched_scales(offsets[h], joints[:, h], storyboard, h) if storyboard is not None
              else dict.fromkeys(BODY_PARTS, 1.0) for h in people]
    root = joints[:, :, 0] * np.array([(1.0, s["legs"], 1.0) for s in scales])
    offsets = offsets * np.stack([scale_per_bone(s) for s in scales])[..., None]
    fitted = inverse_kinematics(joints, offsets)
    spread = [spread_flips(joints[:, h], fitted[:, h], offsets[h]) for h in people]
    _, out = steady_rotations(joints, root, np.stack([fit for fit, _ in spread], 1), offsets)
    for h, (_, turned) in zip(people, spread):
        if len(turned):
            feet = forward_kinematics(root[turned, h], fitted[turned, h], offsets[h])[:, list(FEET)]
            out[turned, h] = reach_with_legs(out[turned, h], feet)   # a turn is made on the feet
    return out, offsets


def _last_limb_pass(joints: np.ndarray, config: LimbConfig, objects: tuple | None) -> np.ndarray:
    """Knees and elbows smoothed once more (joints (N, H, 22, 3)): the steadying's IK and re-pinned
    hands and feet can leave one popping between its ends (the worst pop of 40 artist-style
    storyboards, 18.7 cm, was a knee). Kept for each person whose largest pop it does not raise."""
    return _kept_where_no_pop_grows(joints, steady_limbs(joints, config, objects))


def _kept_where_no_pop_grows(joints: np.ndarray, changed: np.ndarray) -> np.ndarray:
    """joints (N, H, 22, 3) with each person's `changed` motion where it does not raise their
    largest pop."""
    out = joints.copy()
    for h in range(joints.shape[1]):
        if frame_pops(changed[:, h]).max() <= frame_pops(joints[:, h]).max():
            out[:, h] = changed[:, h]
    return out


def lasting_as_long(config, fps: float):
    """A finishing config whose durations (frames at TUNED_FPS) last as long at `fps` frames per
    second: a lock blends in over 0.15 s whatever the clip's rate."""
    scale = fps / TUNED_FPS
    if scale == 1.0:
        return config
    return replace(config, **{name: max(1, round(value * scale)) if isinstance(value, int) else value * scale
                              for name in config.DURATIONS for value in [getattr(config, name)]})


def finish(clip: MotionClip, storyboard: Storyboard, config: FinishConfig = FinishConfig(),
           checkpoint: Callable[[], None] = lambda: None) -> MotionClip:
    """The clip (people in the storyboard's agent order) with its constraints made exact.
    `checkpoint` runs between the stages; what it raises stops the finishing (a run cancelled in
    the app's generation process stops there, app.engine_process)."""
    config = replace(config, **{f.name: lasting_as_long(getattr(config, f.name), clip.fps) for f in fields(config)
                                if hasattr(getattr(config, f.name), "DURATIONS")})
    if config.contacts:
        storyboard = with_generated_contacts(clip, storyboard, config.inferred)
    joints = retime_to_keys(np.asarray(clip.joints, float), storyboard)
    storyboard = with_hold_ends(storyboard)
    joints, offsets = consistent_skeleton(joints, storyboard)
    checkpoint()
    if config.keyposes:
        joints = warp_to_keyposes(joints, offsets, storyboard, config.warp)
        checkpoint()
    if config.paths:
        joints = follow_paths(joints, storyboard, config.path, clip.fps)
        checkpoint()
    if config.polish and config.contacts and clip.obj_pose is not None and storyboard.objects:   # before the feet plant
        joints = step_within_reach(joints, np.asarray(clip.obj_pose, float), storyboard, config.contact)
    if config.feet:  # before the object: hands that hold it must not move after it is placed
        keys = key_frames(storyboard)   # the warp placed these poses: feet plant where they stand
        joints = lock_feet(settle_on_ground(joints, config.foot), clip.fps, config.foot, keys)
        checkpoint()
    kw = {}
    if config.contacts and clip.obj_pose is not None and storyboard.objects:
        pose = hold_object(joints, np.asarray(clip.obj_pose, float), storyboard, config.contact)
        checkpoint()
        if config.polish:
            joints = crouch_to_grips(joints, pose, storyboard, config.contact)
            checkpoint()
        kw = dict(obj_pose=pose.astype(np.float32), obj_anchors=object_anchors(pose, storyboard).astype(np.float32))
    if config.contacts:
        joints = reach_contacts(joints, kw.get("obj_anchors"), storyboard, config.contact, kw.get("obj_pose"),
                                swivel=config.polish)
        checkpoint()
    obj_pose = kw["obj_pose"].astype(float) if config.contacts and "obj_pose" in kw else None
    if config.polish:
        joints = _polished(joints, offsets, obj_pose, storyboard, config, checkpoint)
    rotations = inverse_kinematics(joints, offsets)
    return replace(clip, joints=joints.astype(np.float32), rot6d=matrix_to_6d(rotations).astype(np.float32),
                   bone_offsets=offsets.astype(np.float32), **kw)


def _polished(joints: np.ndarray, offsets: np.ndarray, obj_pose: np.ndarray | None, storyboard: Storyboard,
              config: FinishConfig, checkpoint: Callable[[], None]) -> np.ndarray:
    """Hands, knees and feet out of the objects (obj_pose (N, O, 7) or None) and pops smoothed:
    joints (N, H, 22, 3)."""
    objects = None if obj_pose is None else (obj_pose, [o.spec for o in storyboard.objects])
    if objects is not None:
        joints = _cleared(joints, obj_pose, storyboard, config.contact)
        checkpoint()
    joints = steady_body(steady_limbs(joints, config.limbs, objects), offsets, storyboard, config.steady)
    checkpoint()
    if obj_pose is not None:
        # The steadying smooths the pops that a push out of an object makes, and so can put the
        # hand back in (a wrist 14 cm deep before its hold): pushed out again, steadied once more
        # with the pushed joints held (smoothed, a released hand went 4 cm back into the box).
        # Knees too (60 artist-style storyboards: a person deeper than 2 cm in an object in 20 of
        # them -> 15, with the knees swivelled out again).
        cleared = _cleared(joints, obj_pose, storyboard, config.contact)
        moved = np.any(cleared != joints, axis=-1)                                  # (N, H, 22)
        pushed = np.flatnonzero(moved.any(axis=(0, 2)))
        if len(pushed):   # one smoothing is enough here (three: 8 ms more a clip, about as many pops)
            joints = steady_body(cleared, offsets, storyboard, replace(config.steady, passes=1), pushed, held=moved)
            checkpoint()
    return _last_limb_pass(joints, config.last_limbs, objects)


def _cleared(joints: np.ndarray, obj_pose: np.ndarray, storyboard: Storyboard, config: ContactConfig) -> np.ndarray:
    """joints (N, H, 22, 3) with feet, knees, hands and elbows out of the objects at obj_pose (N, O, 7)."""
    joints = clear_feet(joints, obj_pose, storyboard, config.clear_frames)
    specs = [o.spec for o in storyboard.objects]
    joints = clear_hands(clear_knees(joints, obj_pose, specs, config), obj_pose, storyboard, config.clear_frames)
    # Elbows swivelled out too (penetration within 2 cm, as in held.py: 89, 90, 82, 77 -> 90, 93,
    # 89, 79), where no pop grows: the steadying after holds them, and an elbow that reach_contacts
    # left jumping 40 cm in a frame stayed so (pops within 5 cm 91, 90, 86, 83 -> 89, 86, 85, 81).
    return _kept_where_no_pop_grows(joints, clear_elbows(joints, obj_pose, specs, config))
