"""Posing a keypose like a rig, in the sketch plane (pure numpy: the app's canvas calls it per drag,
and the artist-style benchmark poses its figures with it, as an artist on the canvas would).

A keypose is 22 points (22, 2) of the skeleton (engine.skeleton's hierarchy). Dragging one point
moves the figure the way an animator's rig would, keeping every bone's drawn length but where
a limb straightens:

    pelvis                 the whole figure moves
    wrist, ankle           two-bone IK from the shoulder or hip, the elbow or knee bending the
                           way it bends now; the foot rides on the ankle. Dragged beyond its
                           reach, a limb first straightens out of depth (given the standing
                           template: its two drawn bones grow alike, up to STRAIGHTEN times the
                           template's limb at the figure's scale); a wrist then leans the chest
                           towards it (as a spine3 drag does, by at most MAX_LEAN degrees), as a
                           body reaching for something does, the other hand staying where it was
                           while its arm reaches it
    spine joints           a chest control: the spine bends from the pelvis to put the joint
                           there, all above it moves along without turning (turning its own
                           short bone folded the chest 60 degrees for a 15 cm drag)
    neck, head             the neck bends from the chest the same way; the shoulders stay
    any other joint        FK: its bone turns about its parent, everything below it with it
    Shift + drag           the whole figure turns about the pelvis (the dragged joint follows
                           the pointer's direction)
    Ctrl + drag            the whole figure scales about the pelvis
    Alt + drag             only that point moves (free placement)

Pinned joints stay where they are while others move: a pinned wrist or ankle re-solves its limb
by IK to stay put (move the pelvis with the feet pinned: the legs bend); other pinned joints are
restored after the move. Unplaced joints (mask False) neither move nor constrain.
"""
from __future__ import annotations

import numpy as np

from engine.skeleton import CHILDREN, JOINT_INDEX, PARENTS

PELVIS = JOINT_INDEX["pelvis"]
# End effector -> (chain root, middle joint) for two-bone IK.
LIMB_ENDS = {JOINT_INDEX[f"{s}_{end}"]: (JOINT_INDEX[f"{s}_{root}"], JOINT_INDEX[f"{s}_{mid}"])
             for s in "lr" for root, mid, end in (("shoulder", "elbow", "wrist"), ("hip", "knee", "ankle"))}
MODES = ("rig", "rotate", "scale", "free")
# Chains a dragged joint bends from a fixed root: the spine from the pelvis (a chest control), the
# neck from the chest (the head looks, the shoulders stay).
CHAINS = [(PELVIS, [JOINT_INDEX[n] for n in ("spine1", "spine2", "spine3")]),
          (JOINT_INDEX["spine3"], [JOINT_INDEX[n] for n in ("neck", "head")])]
# A dragged joint -> (the root it bends from, the chain up to it).
BENDS = {j: (root, chain[:i + 1]) for root, chain in CHAINS for i, j in enumerate(chain)}
CHEST = JOINT_INDEX["spine3"]
WRISTS = (JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"])
MAX_LEAN = 35        # degrees the chest may turn about the pelvis towards a hand dragged beyond reach ...
LEAN_HEIGHT = 0.85   # ... keeping this share of its distance from the pelvis
# How much longer than the standing template's a limb may be drawn: the template hangs its limbs
# down, seen from the camera's elevation (at 20 degrees 94% of their length shows), and bodies run
# up to 10% larger than it (finishing's sketched_scales). Kept to the template's lengths, a posed
# figure's hand or foot stopped short of where the artist put it in half of the drags, by 10 cm
# (artist-style benchmark: the synthesized people's legs are 13% longer than the template shows).
STRAIGHTEN = 1.15


def _subtree(joint: int) -> list[int]:
    return [joint] + [d for c in CHILDREN[joint] for d in _subtree(c)]


SUBTREE = [_subtree(j) for j in range(len(PARENTS))]


def _rotate(points: np.ndarray, centre: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    rel = points - centre
    return centre + rel @ np.array([[c, s], [-s, c]])


def _angle(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


def two_bone_2d(root: np.ndarray, mid: np.ndarray, end: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(middle, end) of a two-bone chain from a fixed root reaching for target (each (2,)), with
    the bones' current lengths and bend side; out of reach, the straight chain points at it."""
    upper, lower = np.linalg.norm(mid - root), np.linalg.norm(end - mid)
    to_target = target - root
    dist = float(np.clip(np.linalg.norm(to_target), abs(upper - lower) + 1e-9, upper + lower - 1e-9))
    direction = to_target / max(np.linalg.norm(to_target), 1e-12)
    cos_root = (upper ** 2 + dist ** 2 - lower ** 2) / (2 * upper * dist) if upper > 0 else 1.0
    a, b = end - root, mid - root
    bend = np.sign(a[0] * b[1] - a[1] * b[0]) or 1.0            # which side the middle joint is on
    angle = bend * np.arccos(np.clip(cos_root, -1.0, 1.0))
    c, s = np.cos(angle), np.sin(angle)
    middle = root + upper * np.array([c * direction[0] - s * direction[1], s * direction[0] + c * direction[1]])
    return middle, root + dist * direction


def _reach(points: np.ndarray, mask: np.ndarray, end: int, target: np.ndarray, longest: float = 0.0) -> None:
    """Re-solve end's limb in place so that end reaches target (all of its chain placed); a limb
    shorter than `longest` (m, both bones) that does not reach straightens out of depth first: both
    bones grow alike, up to that."""
    root, mid = LIMB_ENDS[end]
    if not mask[[root, mid, end]].all():
        points[end] = target
        return
    old_end = points[end].copy()
    limb = _limb(points, end)
    grow = np.clip(np.linalg.norm(target - points[root]), limb, max(longest, limb)) / max(limb, 1e-12)
    elbow = points[root] + grow * (points[mid] - points[root])
    points[mid], points[end] = two_bone_2d(points[root], elbow, elbow + grow * (points[end] - points[mid]), target)
    for j in SUBTREE[end][1:]:                                  # the foot rides on the ankle
        points[j] += points[end] - old_end


def _lean_towards(points: np.ndarray, mask: np.ndarray, wrist: int, target: np.ndarray,
                  pinned: tuple[int, ...], longest: float = 0.0) -> np.ndarray:
    """points (22, 2) with the chest bent towards target (2,) (as a spine3 drag bends it) until the
    wrist's arm (straightened to `longest` where that is longer) reaches it, the chest turning at most MAX_LEAN degrees about the pelvis and
    coming no closer to it than LEAN_HEIGHT of its distance (a reach for the floor folded the
    spine in two); unchanged when the arm reaches already, or the upper body is unplaced or
    pinned (a pinned wrist re-reaches its place after)."""
    shoulder = LIMB_ENDS[wrist][0]
    root, chain = BENDS[CHEST]
    upper = SUBTREE[chain[0]]
    if not mask[[root, *upper]].all() or set(pinned) & (set(upper) - set(WRISTS)):
        return points
    arm = max(_limb(points, wrist), longest)
    upright = points[CHEST] - points[root]
    height = float(np.linalg.norm(upright))
    out = points
    for _ in range(3):   # the chest moves on its spine's reach about the pelvis: a few passes
        gap = target - out[shoulder]
        short = np.linalg.norm(gap) - arm
        if short < 1e-6:
            break
        goal = out[CHEST] + short * _unit(gap) - points[root]
        turn = (_angle(goal) - _angle(upright) + np.pi) % (2 * np.pi) - np.pi        # the shorter way round
        turn = np.clip(turn, -np.deg2rad(MAX_LEAN), np.deg2rad(MAX_LEAN))
        reach = np.clip(np.linalg.norm(goal), LEAN_HEIGHT * height, height)
        out = _bend_chain(points, root, chain, points[root] + reach * _unit(_rotate(upright, np.zeros(2), turn)))
    return out


def _limb(points: np.ndarray, end: int) -> float:
    """Length (m) of end's two-bone limb in points (22, 2)."""
    root, mid = LIMB_ENDS[end]
    return float(np.linalg.norm(points[mid] - points[root]) + np.linalg.norm(points[end] - points[mid]))


def _figure_scale(points: np.ndarray, mask: np.ndarray, template: np.ndarray) -> float:
    """How much larger than the template (22, 2) the figure points (22, 2) is drawn: the median
    over its placed bones of their length over the template's (a few straightened or foreshortened
    bones leave it; a figure scaled with Ctrl scales it)."""
    bones = [j for j in range(1, len(PARENTS)) if mask[j] and mask[PARENTS[j]]]
    if not bones:
        return 1.0
    drawn = np.linalg.norm(points[bones] - points[[PARENTS[j] for j in bones]], axis=-1)
    own = np.linalg.norm(template[bones] - template[[PARENTS[j] for j in bones]], axis=-1)
    return float(np.median(drawn / np.maximum(own, 1e-9)))


def _keep_hand(points: np.ndarray, mask: np.ndarray, before: np.ndarray, wrist: int) -> None:
    """The other hand, which a lean carried off, back where it was (in place; its arm re-solved)
    where its arm still reaches that: as an IK rig's hand control, it stays where the artist put it
    (carried along, a left hand placed first moved 8 cm as the right one was dragged beyond reach)."""
    shoulder = LIMB_ENDS[wrist][0]
    if mask[wrist] and np.linalg.norm(before[wrist] - points[shoulder]) <= _limb(points, wrist):
        _reach(points, mask, wrist, before[wrist])


def _bend_chain(points: np.ndarray, root: int, chain: list[int], target: np.ndarray) -> np.ndarray:
    """points (22, 2) with the dragged joint chain[-1] moved to `target` like a rig's control: the
    bones from `root` (fixed) up the chain bend to reach it (FABRIK, bone lengths kept; out of
    reach they straighten towards it), each bone's side branches turning with it, and everything
    above the dragged joint moves along without turning."""
    out = points.copy()
    joints = [root, *chain]
    pos = points[joints].copy()
    lengths = np.linalg.norm(np.diff(pos, axis=0), axis=-1)
    for _ in range(10):
        pos[-1] = target
        for k in range(len(pos) - 2, -1, -1):       # from the dragged joint down ...
            pos[k] = pos[k + 1] + lengths[k] * _unit(pos[k] - pos[k + 1])
        pos[0] = points[root]
        for k in range(1, len(pos)):                # ... and back up from the root
            pos[k] = pos[k - 1] + lengths[k - 1] * _unit(pos[k] - pos[k - 1])
    for k, j in enumerate(joints[1:-1], start=1):   # each bone's own turn carries its side branches
        turn = _angle(pos[k + 1] - pos[k]) - _angle(points[joints[k + 1]] - points[j])
        side = [d for c in CHILDREN[j] if c != joints[k + 1] for d in SUBTREE[c]]
        out[side] = _rotate(points[side] - points[j] + pos[k], pos[k], turn)
        out[j] = pos[k]
    above = SUBTREE[chain[-1]]
    out[above] = points[above] + pos[-1] - points[chain[-1]]
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def drag_pose(points: np.ndarray, mask: np.ndarray, joint: int, target, mode: str = "rig",
              pinned: tuple[int, ...] = (), template: np.ndarray | None = None) -> np.ndarray:
    """The pose (22, 2) after `joint` of `points` (22, 2; mask (22,) bool: placed) is dragged to
    target (2,) in `mode` (MODES), keeping `pinned` joints where they are; `template` (22, 2), the
    standing figure in the same camera (engine.poses), lets a limb straighten (STRAIGHTEN)."""
    target = np.asarray(target, float)
    before = np.asarray(points, float)
    out = before.copy()
    pelvis = before[PELVIS] if mask[PELVIS] else before[mask].mean(0)
    if mode == "free":
        out[joint] = target
        return out
    if mode in ("rotate", "scale"):
        if np.linalg.norm(before[joint] - pelvis) < 1e-9:
            return out
        if mode == "rotate":
            out = _rotate(before, pelvis, _angle(target - pelvis) - _angle(before[joint] - pelvis))
        else:
            ratio = np.linalg.norm(target - pelvis) / np.linalg.norm(before[joint] - pelvis)
            out = pelvis + (before - pelvis) * max(ratio, 0.05)
    elif joint == PELVIS:
        out += target - before[PELVIS]
    elif joint in LIMB_ENDS:
        longest = 0.0 if template is None else STRAIGHTEN * _figure_scale(before, mask, template) * _limb(template, joint)
        if joint in WRISTS:
            out = _lean_towards(out, mask, joint, target, pinned, longest)
            _keep_hand(out, mask, before, next(w for w in WRISTS if w != joint))
        _reach(out, mask, joint, target, longest)
    elif joint in BENDS and mask[[BENDS[joint][0], *BENDS[joint][1]]].all():
        out = _bend_chain(before, *BENDS[joint], target)
    else:
        parent = PARENTS[joint]
        pivot = before[parent] if mask[parent] else before[joint]
        angle = _angle(target - pivot) - _angle(before[joint] - pivot)
        moved = SUBTREE[joint]
        out[moved] = _rotate(before[moved], pivot, angle)
    for j in pinned:               # pinned limb ends re-reach their place; other pins are restored
        if mask[j] and np.linalg.norm(out[j] - before[j]) > 1e-12 and j != joint:
            if j in LIMB_ENDS and LIMB_ENDS[j][0] not in pinned:
                _reach(out, mask, j, before[j])
            else:
                out[j] = before[j]
    return np.where(mask[:, None], out, before)
