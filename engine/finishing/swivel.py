"""Elbows and knees that keep limbs out of the objects: where an arm reaching its grip would pass
through an object, its elbow swivels about the shoulder-wrist line (which keeps both bone lengths)
to where it does not, or least does, choosing the angles of a run of frames together so that the
elbow turns smoothly (reach_contacts calls it); so does a knee about the hip-ankle line
(clear_knees: a person crouching beside a box on the floor put a knee 4-7 cm into it).
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import binary_dilation, gaussian_filter1d

from ..body import JOINT_RADII
from ..geometry.rotations import cross, normalize
from ..objects import ObjectSpec, world_to_local
from ..skeleton import ANKLES, ELBOWS, HANDS, HIPS, KNEES, SHOULDERS

SWIVELS = np.deg2rad(np.arange(-180, 180, 5))  # elbow angles about the shoulder-wrist line tried
                                               # to take a forearm out of an object (0 included)


def _limb_radii(root: int, mid: int, end: int) -> np.ndarray:
    """(3,) engine.metrics' radii of a limb's upper middle, middle joint and lower middle."""
    r, m, e = (JOINT_RADII[j] for j in (root, mid, end))
    return np.array([(r + m) / 2, m, (m + e) / 2])


ARM_RADII = _limb_radii(SHOULDERS[0], ELBOWS[0], HANDS[0])
LEG_RADII = _limb_radii(HIPS[0], KNEES[0], ANKLES[0])


def limb_penetration(root: np.ndarray, mid: np.ndarray, end: np.ndarray, obj_pose: np.ndarray,
                     specs: list[ObjectSpec], radii: np.ndarray = ARM_RADII, ground: bool = True) -> np.ndarray:
    """Deepest penetration (M, C), 0 where none, of a limb's spheres (upper middle, middle joint,
    lower middle: ARM_RADII or LEG_RADII) into any object or (`ground`) the floor. root, end
    (M, 1, 3); mid (M, C, 3) C candidates; obj_pose (M, O, 7). The end is left out: a wrist holds
    on at its grip, an ankle stands where its foot is planted."""
    points = np.stack(np.broadcast_arrays((root + mid) / 2, mid, (mid + end) / 2), axis=2)  # (M, C, 3, 3)
    m, c = mid.shape[:2]
    depth = np.maximum(np.max(radii - points[..., 1], axis=-1), 0.0) if ground else np.zeros((m, c))
    for o, spec in enumerate(specs):
        local = world_to_local(points.reshape(m, -1, 3), obj_pose[:, o]).reshape(points.shape)
        depth = np.maximum(depth, np.max(spec.penetration_local(local, radii), axis=-1))
    return depth


def clear_knees(joints: np.ndarray, obj_pose: np.ndarray, specs: list[ObjectSpec], config) -> np.ndarray:
    """joints (N, H, 22, 3) with every knee that passes through an object (obj_pose (N, O, 7))
    swivelled about its hip-ankle line, as swivel_clear turns elbows (config: a ContactConfig);
    hips, ankles and feet stay. The floor is left out: a knee kneels on it."""
    return _swivelled_clear(joints, obj_pose, specs, config, zip(HIPS, KNEES, ANKLES), LEG_RADII, ground=False)


def clear_elbows(joints: np.ndarray, obj_pose: np.ndarray, specs: list[ObjectSpec], config) -> np.ndarray:
    """joints (N, H, 22, 3) with every arm that passes through an object (obj_pose (N, O, 7)) or
    the floor swivelled about its shoulder-wrist line, as clear_knees turns knees: the steadying
    after reach_contacts turned forearms back into boxes beside their grips (by up to 4 cm)."""
    return _swivelled_clear(joints, obj_pose, specs, config, zip(SHOULDERS, ELBOWS, HANDS), ARM_RADII, ground=True)


def _swivelled_clear(joints: np.ndarray, obj_pose: np.ndarray, specs: list[ObjectSpec], config, limbs,
                     radii: np.ndarray, ground: bool) -> np.ndarray:
    """joints (N, H, 22, 3) with the middle joint of each limb (root, middle, end joint) that
    passes through an object swivelled off it (swivel_clear), and over config.knee_ease_frames
    either side, where it is clear, so that it swings out and back smoothly (a knee one frame in
    a box swung 16 cm out and back at once)."""
    out = joints.copy()
    for root, mid, end in limbs:
        r, m, e = (joints[..., j, :] for j in (root, mid, end))                  # (N, H, 3)
        sunk = limb_penetration(r.reshape(-1, 1, 3), m.reshape(-1, 1, 3), e.reshape(-1, 1, 3),
                                np.repeat(obj_pose, joints.shape[1], 0), specs, radii, ground)
        around = np.ones((2 * config.knee_ease_frames + 1, 1), bool)
        frames, people = np.nonzero(binary_dilation(sunk.reshape(joints.shape[:2]) > 0, around))
        if not len(frames):
            continue
        runs = frame_runs(frames, people)
        out[frames, people, mid] = swivel_clear(r[frames, people], m[frames, people], e[frames, people],
                                                obj_pose[frames], specs, config, runs, radii, ground)
    return out


def frame_runs(frames: np.ndarray, people: np.ndarray) -> list[np.ndarray]:
    """Index arrays into (frames, people) (M,) of each person's runs of consecutive frames."""
    runs = []
    for h in np.unique(people):
        index = np.flatnonzero(people == h)                       # in frame order
        runs += np.split(index, np.flatnonzero(np.diff(frames[index]) > 1) + 1)
    return runs


def _swivelled(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Elbows (M, 3) turned about the shoulder-wrist line (which keeps both bone lengths) by
    angles (M,) or, for candidates, (M, C) radians -> (M, 3) or (M, C, 3)."""
    axis = normalize(wrist - shoulder)
    centre = shoulder + np.sum((elbow - shoulder) * axis, -1, keepdims=True) * axis
    out = elbow - centre
    if angles.ndim == 2:
        axis, centre, out = axis[:, None], centre[:, None], out[:, None]
    cos, sin = np.cos(angles)[..., None], np.sin(angles)[..., None]
    return centre + cos * out + sin * cross(axis, out)


def swivel_clear(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray, obj_pose: np.ndarray,
                  specs: list[ObjectSpec], config, runs: list[np.ndarray], radii: np.ndarray = ARM_RADII,
                  ground: bool = True) -> np.ndarray:
    """Elbows (M, 3) swivelled about the shoulder-wrist line to trade penetration into the objects
    (obj_pose (M, O, 7)) against turning (config.swivel_cost metres of penetration per radian)
    and against turning fast (config.swivel_change_cost per squared radian between frames): `runs`
    are index arrays of the consecutive frames of one arm, along which the angles are chosen
    together (a per-frame choice flipped elbows to the other side in one frame, by up to 40 cm).
    shoulder, elbow, wrist (M, 3) (or a leg's hip, knee, ankle, with its radii and `ground`:
    limb_penetration's)."""
    # A run whose arm is clear of every object as it is keeps its elbow: turning costs, so not
    # turning is its cheapest path (most held frames; the candidates cost 60% of the finishing's
    # contacts pass).
    clear = limb_penetration(shoulder[:, None], elbow[:, None], wrist[:, None], obj_pose, specs, radii, ground)[:, 0] <= 0
    runs = [run for run in runs if not clear[run].all()]
    if not runs:
        return elbow
    turn = np.angle(np.exp(1j * (SWIVELS[:, None] - SWIVELS[None])))                  # (C, C) wrapped
    change = config.swivel_change_cost * turn ** 2
    out = elbow.copy()
    for run in runs:
        grid = np.broadcast_to(SWIVELS, (len(run), len(SWIVELS)))
        candidates = _swivelled(shoulder[run], elbow[run], wrist[run], grid)            # (T, C, 3)
        depth = limb_penetration(shoulder[run, None], candidates, wrist[run, None], obj_pose[run], specs, radii, ground)
        path = _cheapest_path(depth + config.swivel_cost * np.abs(SWIVELS), change)
        smooth = gaussian_filter1d(np.unwrap(SWIVELS[path]), config.swivel_sigma, mode="nearest")
        out[run] = _swivelled(shoulder[run], elbow[run], wrist[run], smooth)
    return out


def _cheapest_path(score: np.ndarray, change: np.ndarray) -> np.ndarray:
    """Viterbi: the candidate per step (T,) minimising sum score[t, c_t] + change[c_t-1, c_t]."""
    total, back = score[0].copy(), np.zeros(score.shape, int)
    for t in range(1, len(score)):
        options = total[:, None] + change                                          # from -> to
        back[t] = np.argmin(options, axis=0)
        total = options[back[t], np.arange(score.shape[1])] + score[t]
    path = np.empty(len(score), int)
    path[-1] = int(np.argmin(total))
    for t in range(len(score) - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path
