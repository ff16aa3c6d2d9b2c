"""Contacts: hands on their grips, or on the partner's hand.

`reach_contacts` moves each contact's wrist onto its grip (or the other person's hand) by exact
two-bone IK from the shoulder, on joint positions (N frames, H people, 22 joints, world metres,
Y up), eased in before the span and out after it. Only elbows and wrists move, and every bone
keeps its length; an elbow whose arm would pass through an object swivels about the
shoulder-wrist line until it does not (swivel.py). The objects' poses come first, from the
holding hands (held.py); ContactConfig is the settings of both.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..body import JOINT_RADII
from ..geometry.rotations import cross, norm, normalize
from ..objects import local_to_world, world_to_local
from ..skeleton import ELBOWS, HANDS, SHOULDERS
from ..storyboard import HANDS as HAND_NAMES
from ..storyboard import Contact, Storyboard
from ..synth.reach import UP, continuous_pole, steady_pole, two_bone_ik
from ..synth.trajectory import smoothstep
from .swivel import frame_runs, swivel_clear


@dataclass
class ContactConfig:
    DURATIONS: ClassVar[tuple[str, ...]] = ("blend_frames", "most_handover_frames", "lift_frames", "smooth_sigma",
                                            "reach_smoothing", "frames_per_metre", "swivel_sigma", "clear_frames",
                                            "sunk_frames", "held_clear_frames", "crouch_frames_per_metre",
                                            "lean_frames_per_radian", "crouch_sigma", "lean_sigma",
                                            "key_ease_frames", "step_ease_frames", "knee_ease_frames",
                                            "drawn_falloff", "path_smoothing")
    blend_frames: int = 6          # frames a hand eases onto its grip before a span and off after it
    sunk_frames: int = 18          # frames before (after) a span within which a hand inside the object holds on
    handover_pop: float = 0.02     # m a grip may spike where a held object eases out the turn that a hand
    most_handover_frames: int = 16  # joining or leaving the hold makes (over blend_frames to these frames)
    lift_frames: int = 6           # frames a resting object eases into the holding hands' fit (and,
                                   # at least, a released one slides to its sketched landing place)
    smooth_sigma: float = 1.5      # frames: Gaussian smoothing of a held object's fitted path
    drawn_falloff: int = 12        # frames over which a held object's move onto its drawn outline fades (held.py)
    path_smoothing: float = 2.0    # frames; Gaussian sigma of a held object's move onto its drawn path (held.py)
    rest_height: float = 0.0       # m the base of a resting object sits above the ground
    hand_gap: float = 0.09         # m between two clasped wrists (the synthesizer's handshake grip)
    min_spread: float = 1e-4       # m^2: grip spread below which the yaw fit is undefined (one hand)
    clear_iterations: int = 4      # pushes of a held object out of its holders' bodies, and of a resting one
                                   # out of anybody's (0: none)
    held_clear_frames: float = 1.0  # time scale over which a held object's push out of its holders eases
                                   # (held.py; over 1.5 frames it put more grips beyond reach: posed
                                   # artist-style grips within 3 cm 87 -> 82%, at 1.0 85%)
    most_rest_shift: float = 0.2   # m a resting object may slide from where it lies to be clear of the bodies ...
    rest_reach_slack: float = 0.05  # m ... and put a grip further beyond reach of the hands that take it next
                                   # (none kept a table in two carriers' reach, but left a knee in a box
                                   # before its pick-up: artist-style penetration within 2 cm 55 -> 52%)
    swivel_cost: float = 0.005     # m of penetration worth turning an elbow by one radian
    swivel_change_cost: float = 0.02   # m of penetration worth a one-radian turn between frames
                                       # (squared: a turn spread over frames costs less; at 0.01 and
                                       # 0.05, forearms stayed in boxes beside their grips: artist-style
                                       # penetration within 2 cm 85, 81, 76 -> 89, 86, 79 of 100 on
                                       # three drawings of 50 scenes, pops the same)
    knee_ease_frames: int = 4      # frames either side of a knee's (or a cleared elbow's) stay in an object
                                   # over which it swivels too (none: a one-frame stay swung the knee
                                   # 16 cm out and back)
    swivel_sigma: float = 0.75     # frames at TUNED_FPS; smoothing of the chosen swivel angles (1.5
                                   # turned forearms back into boxes beside side grips: artist-style
                                   # penetration within 2 cm 14 -> 15 of 20, pops the same)
    clear_frames: float = 1.5      # time scale over which a free hand's push out of an object eases (clearance.py)
    reach: float = 0.95            # share of the straight arm's length a holder may reach without stepping
    reach_passes: int = 2          # steps towards the grips (smoothing leaves part of each one undone)
    reach_smoothing: float = 3.0   # frames; Gaussian sigma of a holder's step offsets
    frames_per_metre: float = 25.0  # frames a holder's step offset takes to grow by a metre away from a key
    key_ease_frames: float = 1.5   # frames over which a step or crouch away from a key eases in (growing
                                   # at full pace from the key, it kinked there: 4 cm of the whole body in
                                   # a frame; artist-style pops within 5 cm on three drawings of 50
                                   # scenes 88, 82, 77 -> 86, 87, 85 of 100; over 3 frames, 89, 87, 84,
                                   # but grips beyond reach near keys and a knee pop of 11 cm)
    step_ease_frames: int = 2      # frames over which a step eases into the room a key leaves it (cut
                                   # off there at once, a body turned back in a frame: pops within 5 cm
                                   # 86, 87, 85 -> 91, 89, 86; 2 of 300 grips beyond 3 cm against 1)
    grip_rise: float = 0.9         # share of the reach a held grip may lie below or above its shoulder
    crouch_frames_per_metre: float = 50.0   # frames a holder takes to crouch a metre to grips below its
                                   # reach (crouch.py; 2 cm a frame at 20 fps: at 3, 20 artist-style
                                   # storyboards' largest pops within 5 cm 15 -> 14, the worst 6.8 -> 7.4 cm) ...
    crouch_sigma: float = 1.5      # ... smoothed over this many frames ...
    lean_sigma: float = 6.0        # frames over which a holder leans forward for what a squat leaves (at 4,
                                   # 20 artist-style storyboards' pops within 5 cm 15 -> 14) ...
    lean_frames_per_radian: float = 38.2   # ... upright at its keys, straightening at most a radian in this many
                                   # frames (1.5 degrees a frame; at 3, pops within 5 cm 16 -> 14 of 20) ...
    lowest_squat: float = 0.7      # ... the pelvis no lower than this share of the legs' length ...
    most_lean: float = 65.0        # ... nor the trunk further than this from upright (degrees)


def anchor_table(storyboard: Storyboard) -> np.ndarray:
    """Every object's local anchors padded to the longest list by repeating its last one:
    (O, K, 3), K as in engine.controls (flat anchor index o * K + k). An object without anchors
    (nothing may hold it) stands in with its centre."""
    k_max = max([len(o.spec.anchors) for o in storyboard.objects] + [1])
    lists = [o.spec.anchors if len(o.spec.anchors) else np.zeros((1, 3)) for o in storyboard.objects]
    padded = [np.concatenate([a, np.repeat(a[-1:], k_max - len(a), axis=0)]) for a in lists]
    return np.array(padded).reshape(-1, k_max, 3)


def object_anchors(obj_pose: np.ndarray, storyboard: Storyboard) -> np.ndarray:
    """World grip positions of every object: obj_pose (N, O, 7) -> (N, O, K, 3)."""
    return local_to_world(anchor_table(storyboard)[None], np.asarray(obj_pose, float))


def forward_of(joints: np.ndarray) -> np.ndarray:
    """Unit horizontal facing direction from the shoulders: (..., 22, 3) -> (..., 3)."""
    return normalize(cross(joints[..., SHOULDERS[0], :] - joints[..., SHOULDERS[1], :], UP))


def arm_lengths(joints: np.ndarray) -> np.ndarray:
    """Shoulder-to-elbow plus elbow-to-wrist length of each arm: (N, H, 22, 3) -> (N, H, 2)."""
    shoulder, elbow, wrist = (joints[:, :, list(j)] for j in (SHOULDERS, ELBOWS, HANDS))
    return norm(elbow - shoulder) + norm(wrist - elbow)


def span_weight(n: int, start: int, end: int, blend: int) -> np.ndarray:
    """1 on [start, end], easing smoothly to 0 over `blend` frames either side. -> (N,)."""
    outside = np.maximum(np.maximum(start - np.arange(n), np.arange(n) - end), 0)
    return smoothstep(1.0 - outside / (blend + 1))


def _held_span(c: Contact, wrist: np.ndarray, obj_pose: np.ndarray | None, storyboard: Storyboard,
               config: ContactConfig) -> tuple[int, int]:
    """The frames [start, end] contact c's hand is on its grip: its span, widened to the frames
    within `sunk_frames` of it at which the generated wrist (N, 3) lies inside the object (at
    obj_pose (N, O, 7)). A hand the artist's span has not reached yet, or has let go of, went
    through the box or under a table's top and was pushed out with a pop; on its grip, it waits
    there (artist-style storyboards with nothing over 2 cm inside an object 47 -> 53%)."""
    if obj_pose is None:
        return c.start, c.end
    o = storyboard.object_index(c.object)
    local = world_to_local(wrist[:, None], obj_pose[:, o])[:, 0]
    inside = np.flatnonzero(storyboard.objects[o].spec.sdf_local(local) < JOINT_RADII[HANDS[0]])
    before = inside[(inside < c.start) & (inside >= c.start - config.sunk_frames)]
    after = inside[(inside > c.end) & (inside <= c.end + config.sunk_frames)]
    return (before.min() if len(before) else c.start), (after.max() if len(after) else c.end)


def _contact_targets(joints: np.ndarray, obj_anchors: np.ndarray | None, storyboard: Storyboard,
                     config: ContactConfig, obj_pose: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Where each wrist should be and how much: targets (N, H, 2, 3), weights (N, H, 2).
    Around an object's span (_held_span, with the objects' poses obj_pose (N, O, 7)) the target is
    the grip where it is then; around a partner's hand, where it is at the span's start and end."""
    n, h = joints.shape[:2]
    wrists = joints[:, :, list(HANDS)]
    target, weight = np.zeros((n, h, 2, 3)), np.zeros((n, h, 2))
    k = anchor_table(storyboard).shape[1]

    def put(agent: int, side: int, goal: np.ndarray, w: np.ndarray) -> None:
        stronger = w > weight[:, agent, side]
        target[stronger, agent, side] = goal[stronger]
        weight[stronger, agent, side] = w[stronger]

    for c in storyboard.contacts:
        a, s = storyboard.agent_index(c.agent), HAND_NAMES.index(c.hand)
        if c.object is not None:
            if obj_anchors is None:
                raise ValueError("the storyboard has object contacts but no object anchors were given")
            w = span_weight(n, *_held_span(c, wrists[:, a, s], obj_pose, storyboard, config), config.blend_frames)
            flat = storyboard.object_index(c.object) * k + c.anchor
            # Easing on and off, a hand reaches for the grip where it is then: a box the partner
            # already carries moves on (held still at the span's start, the hand jerked 10 cm as
            # the hold began; left where it let go, it went through the box the partner took on).
            put(a, s, obj_anchors.reshape(n, -1, 3)[:, flat], w)
            continue
        w = span_weight(n, c.start, c.end, config.blend_frames)
        b, t = storyboard.agent_index(c.other_agent), HAND_NAMES.index(c.other_hand)
        frames = np.clip(np.arange(n), c.start, c.end)   # held at the span's start before it, its end after
        mid = 0.5 * (wrists[frames, a, s] + wrists[frames, b, t])
        # Clasped hands sit side by side, a hand's width apart along the line between the people.
        apart = normalize((joints[frames, b, 0] - joints[frames, a, 0]) * [1, 0, 1]) * config.hand_gap / 2
        put(a, s, mid - apart, w)
        put(b, t, mid + apart, w)
    return target, weight


def reach_contacts(joints: np.ndarray, obj_anchors: np.ndarray | None, storyboard: Storyboard,
                   config: ContactConfig = ContactConfig(), obj_pose: np.ndarray | None = None,
                   swivel: bool = True) -> np.ndarray:
    """Put every contact's wrist on its target (reach_with_arms).

    joints (N, H, 22, 3); obj_anchors (N, O, K, 3) (see object_anchors), or None when the
    storyboard has only hand-to-hand contacts. Returns new joints (N, H, 22, 3): elbows and
    wrists of contact arms move, blended in over `blend_frames` before each span and out after.
    With the objects' poses obj_pose (N, O, 7), a hand the generated motion puts inside an object
    near its span holds on there too (_held_span), and elbows swivel off the objects (unless not
    `swivel`: a preview's arms may pass through a box).
    """
    joints = np.asarray(joints, float)
    target, weight = _contact_targets(joints, obj_anchors, storyboard, config, obj_pose)
    return reach_with_arms(joints, target, weight, obj_pose if swivel else None, storyboard, config)


def reach_with_arms(joints: np.ndarray, target: np.ndarray, weight: np.ndarray, obj_pose: np.ndarray | None = None,
                    storyboard: Storyboard | None = None, config: ContactConfig = ContactConfig(),
                    elbows: np.ndarray | None = None) -> np.ndarray:
    """joints (N, H, 22, 3) with each wrist moved `weight` (N, H, 2) of the way to `target`
    (N, H, 2, 3) by two-bone IK from the fixed shoulder (bone lengths exact; a target out of
    reach gets the straightened arm pointing at it); the elbow bends the way it bends now (or
    `weight` of the way towards `elbows` (N, H, 2, 3)), smoothly over frames, and with the objects'
    poses obj_pose (N, O, 7) of the storyboard's objects swivels off them. -> (N, H, 22, 3)"""
    out = joints.copy()
    forward = forward_of(joints)
    for side in range(2):
        moving = weight[..., side] > 0                                    # (N, H)
        shoulder, elbow, wrist = (joints[..., j, :] for j in (SHOULDERS[side], ELBOWS[side], HANDS[side]))
        goal = wrist + weight[..., side, None] * (target[:, :, side] - wrist)   # (N, H, 3)
        # Bend the elbow the way it bends now, smoothly over frames; a straight arm bends down and back.
        axis = normalize(goal - shoulder)
        bend = elbow - shoulder
        if elbows is not None:
            bend = bend + weight[..., side, None] * (elbows[:, :, side] - elbow)
        bend = bend - np.sum(bend * axis, axis=-1, keepdims=True) * axis
        pole = continuous_pole(steady_pole(bend, -UP - forward), axis)[moving]
        shoulder, elbow, wrist, goal = shoulder[moving], elbow[moving], wrist[moving], goal[moving]
        upper = norm(elbow - shoulder, keepdims=True)
        lower = norm(wrist - elbow, keepdims=True)
        new_elbow, new_wrist = two_bone_ik(shoulder, goal, upper, lower, pole)
        if obj_pose is not None and moving.any():
            frames, people = np.nonzero(moving)
            new_elbow = swivel_clear(shoulder, new_elbow, new_wrist, obj_pose[frames],
                                     [o.spec for o in storyboard.objects], config, frame_runs(frames, people))
        out[..., ELBOWS[side], :][moving] = new_elbow
        out[..., HANDS[side], :][moving] = new_wrist
    return out
