"""Held objects: each object a rigid body that moves only in the hands that hold it.

`hold_object` rebuilds each object's pose from the storyboard's contacts and the finished
joints (N frames, H people, 22 joints, world metres, Y up): an upright yaw + translation fit of
its grips to the holding wrists, onto its drawn path and outlines (drawn_holds.py), turning with
the holder's chest while one person alone holds it, eased where hands join or leave the hold, at
a height every holder's arm reaches and moved across towards a holder it is beyond the reach of,
out of the holders' bodies, and lowered onto the ground as it is let go; resting on the ground
before, between and after holds, where the sketch puts it (holds a few frames from each other or
from the clip's ends are one, where the sketch does not put it down: an artist's spans are a few
frames off), slid along the ground out of the legs of people who stand in it. contacts.py then
puts the hands on its grips.

`step_within_reach` comes first: it moves a holder whose grip is beyond arm's reach towards it
(two people carrying one box drift apart along their timing-free paths; an arm cannot close
that gap).
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, minimum_filter1d

from ..body import BONES, body_points
from ..camera import StoryboardCamera
from ..controls import base_path
from ..geometry.rotations import norm, normalize, quat_to_matrix
from ..objects import ObjectSpec, world_to_local
from ..skeleton import ELBOWS, HANDS, JOINT_NAMES, SHOULDERS
from ..storyboard import HANDS as HAND_NAMES
from ..storyboard import Storyboard
from ..synth.props import pose_array
from ..synth.reach import wrap_angle, yaw_matrix
from ..synth.trajectory import smoothstep
from . import held_yaw as headings
from .blend import eased_push
from .contacts import ContactConfig, anchor_table, arm_lengths, forward_of, object_anchors, span_weight
from .drawn_holds import onto_drawing
from .keys import room_from_keys

_ARM = [*ELBOWS, *HANDS]
# engine.metrics' body spheres (joints, then bone midpoints) except the arms', which must touch.
BODY_SPHERES = np.array([j not in _ARM for j in range(len(JOINT_NAMES))]
                        + [child not in _ARM for _, child in BONES])


def _body_spheres(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """joints (N, H, 22, 3) -> the BODY_SPHERES' centres (N, H, S, 3) and radii (S,)."""
    points, radii = body_points(joints)
    return points[:, :, BODY_SPHERES], radii[BODY_SPHERES]


def _grounded(position: np.ndarray, config: ContactConfig) -> np.ndarray:
    """The same horizontal place (3,), resting on the ground."""
    return np.array([position[0], config.rest_height, position[2]])


def true_spans(mask: np.ndarray) -> list[tuple[int, int]]:
    """Inclusive [start, end] frame spans where mask (N,) is True."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1))


def _fit_position(wrists: np.ndarray, grips: np.ndarray, held: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Object origin (N, 3) that puts the mean held grip, turned by yaw (N,), on the mean wrist."""
    w = held[..., None]
    count = np.maximum(w.sum(axis=1), 1)
    turned = np.einsum("nij,nj->ni", yaw_matrix(yaw), np.sum(w * grips, axis=1))
    return (np.sum(w * wrists, axis=1) - turned) / count


def _clear_of_people(pos: np.ndarray, yaw: np.ndarray, spec: ObjectSpec, joints: np.ndarray,
                     holding: np.ndarray, iterations: int, sigma: float) -> np.ndarray:
    """Push a held object (pos (N, 3), yaw (N,)) out in front of each holder (joints
    (N, H, 22, 3), holding (N, H) bool), and from anyone else towards the holders, until no body
    sphere but the arms' is inside it: decoded hands often hang by the hips, and an object fitted
    to them would sit in the pelvis (and a box handed over sat 17 cm into the giver's pelvis after
    the giver let go). Pushes from holders facing each other cancel (there is no room between
    them). The push eases over `sigma` frames as an envelope (blend.eased_push): pushed at one
    frame or two, the held path's smoothing left a box 11 cm inside a chest. Returns pos (N, 3)."""
    points, radii = _body_spheres(joints)
    pelvis = joints[:, :, 0]
    holders = np.sum(holding[..., None] * pelvis, axis=1) / np.maximum(holding.sum(axis=1), 1)[:, None]  # (N, 3)
    # In front of a holder; from anyone else towards the holders, in whose hands it is.
    away = np.where(holding[..., None], forward_of(joints), normalize((holders[:, None] - pelvis) * (1.0, 0.0, 1.0)))
    sunk = np.flatnonzero(holding.any(axis=1))    # pushed only while held, while anything is inside
    pushed = pos.copy()
    for _ in range(iterations):
        if not len(sunk):
            break
        local = world_to_local(points[sunk].reshape(len(sunk), -1, 3), pose_array(pushed[sunk], yaw[sunk]))
        depth = np.max(spec.penetration_local(local.reshape(points[sunk].shape), radii), axis=-1)   # (F, H)
        pushed[sunk] += np.sum(depth[..., None] * away[sunk], axis=1)
        sunk = sunk[depth.any(axis=1)]           # a frame clear of everyone stays so
    return pos + eased_push(pushed - pos, sigma) if np.any(pushed != pos) else pos


def _carried_forward(values: np.ndarray, defined: np.ndarray) -> np.ndarray:
    """values (N, ...) with each frame not `defined` (N,) bool given the value of the last defined
    frame before it, or before any the first defined one."""
    frames = np.arange(len(values))
    last = np.maximum.accumulate(np.where(defined, frames, -1))
    return values[np.where(last >= 0, last, np.argmax(defined))]


def _within_holders_reach(move: np.ndarray, place: np.ndarray, frames: list[int], joints: np.ndarray,
                          grips: np.ndarray, held: np.ndarray, config: ContactConfig) -> np.ndarray:
    """A resting object's slide move (3,) from place (7,), shortened (in tenths) until every grip held
    at `frames` (the frames just before and after the rest) lies at most `rest_reach_slack` further
    beyond its holder's reach than it did unmoved. joints (N, H, 22, 3); grips, held as in _hold_one."""
    n, h = joints.shape[:2]
    if not frames:
        return move
    shoulders = joints[frames][:, :, list(SHOULDERS)].reshape(len(frames), 2 * h, 3)
    reach = config.reach * arm_lengths(joints[frames]).reshape(len(frames), 2 * h)
    turned = np.einsum("ij,fkj->fki", quat_to_matrix(place[3:]), grips[frames])   # (F, 2H, 3)

    def beyond(t: float) -> np.ndarray:
        at = place[:3] + t * move + turned
        return np.where(held[frames], np.maximum(norm(at - shoulders) - reach, 0.0), 0.0)

    unmoved = beyond(0.0)
    t = next((t for t in np.linspace(1.0, 0.0, 11) if np.all(beyond(t) <= unmoved + config.rest_reach_slack)), 0.0)
    return t * move


def _rest_clear_of_people(pose: np.ndarray, joints: np.ndarray, grips: np.ndarray, held: np.ndarray,
                          spec: ObjectSpec, config: ContactConfig) -> np.ndarray:
    """A resting object's pose (N, 7) slid along the ground, over each stretch it lies still and
    unheld (held (N, 2H)), by the least it takes to clear every body sphere but the arms' (which
    reach for it) of joints (N, H, 22, 3), at most `most_rest_shift` and no further out of the
    reach of the hands that hold it just before or after (grips (N, 2H, 3) local), eased in and
    out over `lift_frames` around the stretch. The sketch puts boxes and tables where people walk
    up to them; a knee stood 8-15 cm inside a box drawn on the floor before its pick-up (and a
    table slid 20 cm from the knees of two people shaking hands over it came out of one carrier's
    reach as they lifted it)."""
    n = len(pose)
    still = norm(np.diff(pose[:, :3], axis=0)) < 1e-6
    resting = (np.concatenate([[True], still]) & np.concatenate([still, [True]]) & ~held.any(axis=1)
               & (np.abs(pose[:, 1] - config.rest_height) < 1e-6))
    points, radii = _body_spheres(joints)
    shift, frames, k = np.zeros((n, 3)), np.arange(n), config.lift_frames
    for start, end in true_spans(resting):
        bodies = points[start:end + 1].reshape(-1, 3)
        sizes = np.tile(radii, len(bodies) // len(radii))
        placed, move = pose[start].copy(), np.zeros(3)
        for _ in range(config.clear_iterations):
            placed[:3] = pose[start, :3] + move
            depth = spec.penetration_local(world_to_local(bodies[None], placed[None])[0], sizes)
            if depth.max() <= 0.0:
                break
            away = normalize((placed[:3] + (0.0, spec.size[1] / 2, 0.0) - bodies) * (1.0, 0.0, 1.0))
            move = move + depth.max() * normalize(np.sum(np.maximum(depth, 0.0)[:, None] * away, axis=0))
            move *= min(1.0, config.most_rest_shift / max(float(np.linalg.norm(move)), 1e-9))
        holds = [f for f in (start - 1, end + 1) if 0 <= f < n and held[f].any()]
        move = _within_holders_reach(move, pose[start], holds, joints, grips, held, config)
        weight = np.clip(np.minimum(frames - (start - k), end + k - frames) / k, 0.0, 1.0)   # 1 over the stretch
        shift += smoothstep(weight)[:, None] * move
    return np.concatenate([pose[:, :3] + shift, pose[:, 3:]], axis=1)


def _within_vertical_reach(height: np.ndarray, joints: np.ndarray, grips: np.ndarray, held: np.ndarray,
                           config: ContactConfig) -> np.ndarray:
    """A held object's origin height (N,) moved into the band where every held grip lies within
    `grip_rise` of the reach above or below its holder's shoulder (the middle of the band when
    the holders' bands do not overlap): the mean of a standing and a crouching holder's wrists
    would otherwise put the grips out of both their reaches. joints (N, H, 22, 3); grips, held
    as in _hold_one (N, 2H, 3) local, (N, 2H)."""
    n, h = joints.shape[:2]
    rise = config.grip_rise * config.reach * arm_lengths(joints).reshape(n, 2 * h)
    base = joints[:, :, list(SHOULDERS), 1].reshape(n, 2 * h) - grips[..., 1]   # origin height, grip at the shoulder
    band = held.any(axis=1)                                    # elsewhere the band is the height itself
    low = np.where(band, np.max(np.where(held, base - rise, -np.inf), axis=1), height)
    high = np.where(band, np.min(np.where(held, base + rise, np.inf), axis=1), height)
    return np.where(low <= high, np.clip(height, low, high), (low + high) / 2)


def _within_reach_across(pos: np.ndarray, yaw: np.ndarray, joints: np.ndarray, grips: np.ndarray, held: np.ndarray,
                         config: ContactConfig, iterations: int = 6) -> np.ndarray:
    """A held object's origin (N, 3), turned by yaw (N,), moved across (horizontally) towards the
    holders whose held grips lie beyond `reach` of their shoulders, by the mean of how far those
    lie beyond: the mean of the wrists put one holder's grips out of reach while the other's arms
    were bent. Pulls from the two ends of a shared object cancel where both are short (it stays
    between them). joints (N, H, 22, 3); grips, held as in _hold_one (N, 2H, 3) local, (N, 2H)."""
    n, h = joints.shape[:2]
    shoulders = joints[:, :, list(SHOULDERS)].reshape(n, 2 * h, 3)
    reach = config.reach * arm_lengths(joints).reshape(n, 2 * h)
    turned = np.einsum("nij,nkj->nki", yaw_matrix(yaw), grips)                 # (N, 2H, 3)
    pos = pos.copy()
    for _ in range(iterations):
        to_shoulder = shoulders - pos[:, None] - turned                          # grip -> shoulder
        beyond = np.where(held, np.maximum(norm(to_shoulder) - reach, 0.0), 0.0)
        count = np.maximum(np.count_nonzero(beyond, axis=1), 1)[:, None]
        pos += np.sum(beyond[..., None] * normalize(to_shoulder * (1.0, 0.0, 1.0)), axis=1) / count
    return pos


def sketched_rest(storyboard: Storyboard, o: int, first: int = 0, last: int | None = None) -> np.ndarray | None:
    """Where object o rests on the ground over frames [first, last] according to its sketch (3,),
    or None when nothing sketched falls there. An orthographic sketch gives a grounded object's
    place exactly: each object key's silhouette centre lies on the ray through the object's centre
    (half its height up), and an object path's end points (read as its base's: base_path) are
    the base's projection at the path's first and last frames, where no key is (an outline is the
    surer cue: a path's start wobbles). The cues in range are averaged (hand-drawn ones wobble)."""
    obj = storyboard.objects[o]
    last = storyboard.length - 1 if last is None else last
    half = obj.spec.size[1] / 2
    cam = storyboard.camera
    places = [cam.unproject_to_height((k.outline.min(axis=0) + k.outline.max(axis=0)) / 2, half) - (0.0, half, 0.0)
              for k in storyboard.object_keys if k.object == obj.id and first <= k.frame <= last]
    if not places:   # a path's ends only where no outline is drawn (an artist starts one mid-outline)
        for path in (p for p in storyboard.object_paths if p.object == obj.id):
            points = base_path(storyboard, path)
            places += [cam.unproject_to_height(points[i], 0.0)
                       for i, frame in ((0, path.start), (-1, path.end)) if first <= frame <= last]
    return np.mean(places, axis=0) if places else None


def drawn_in_hands(rest: np.ndarray, held: np.ndarray, spec: ObjectSpec, camera: StoryboardCamera) -> bool:
    """Whether a sketched resting place (3,) of an object is drawn where it is held, at `held`
    (3,): their centres less than the object's largest size apart in the sketch plane (not a
    put-down elsewhere, but the artist's span a few frames off)."""
    centre = np.array([0.0, spec.size[1] / 2, 0.0])
    return bool(np.linalg.norm(camera.project(rest + centre) - camera.project(held + centre)) < max(spec.size))


def _hold_one(joints: np.ndarray, grips: np.ndarray, held: np.ndarray, decoded: np.ndarray,
              spec: ObjectSpec, config: ContactConfig, rests: list[np.ndarray | None],
              camera: StoryboardCamera, drawn: dict[int, np.ndarray],
              paths: list[tuple[int, int, np.ndarray]]) -> np.ndarray:
    """One object's pose (N, 7) from joints (N, H, 22, 3), the local grip each hand holds
    (N, 2H, 3) where held (N, 2H), the decoded pose (N, 7), its sketched resting places, one
    (or None) per gap around the hold spans (see hold_object), the centres of its outlines at
    key frames (frame -> (2,)) and its paths ((start, end, points (L, 2)) each), drawn through
    `camera`."""
    n, h = joints.shape[:2]
    wrists = joints[:, :, list(HANDS)].reshape(n, 2 * h, 3)
    decoded_yaw = headings.yaw_of(decoded[:, 3:])
    still_yaw = np.arctan2(np.mean(np.sin(decoded_yaw)), np.mean(np.cos(decoded_yaw)))
    spans = true_spans(held.any(axis=1))
    if not spans:  # never held: a still object where it was sketched (else decoded), on the ground
        place = rests[0] if rests[0] is not None else np.median(decoded[:, :3], axis=0)
        return _rest_clear_of_people(pose_array(np.tile(_grounded(place, config), (n, 1)), np.full(n, still_yaw)),
                                     joints, grips, held, spec, config)

    fit_yaw, defined = headings.fit_yaw(wrists, grips, held, config.min_spread)
    # One hand cannot turn the object: keep the last defined yaw (before any, the first one).
    fit_yaw = _carried_forward(fit_yaw, defined) if defined.any() else np.full(n, still_yaw)
    holding = held.reshape(n, h, 2).any(axis=-1)                                 # (N, H)
    fit_yaw = headings.carried_yaw(fit_yaw, joints, holding, config.smooth_sigma, grips, held)
    fit_pos = onto_drawing(_fit_position(wrists, grips, held, fit_yaw), fit_yaw, joints, grips, held, spans, drawn,
                           paths, spec, camera, config)
    fit_pos[:, 1] = _within_vertical_reach(fit_pos[:, 1], joints, grips, held, config)
    fit_pos = _within_reach_across(fit_pos, fit_yaw, joints, grips, held, config)
    fit_pos = _clear_of_people(fit_pos, fit_yaw, spec, joints, holding, config.clear_iterations,
                                config.held_clear_frames)
    fit_yaw = headings.eased_handovers(np.unwrap(fit_yaw), held, grips, config)

    # Holds fewer frames apart than a lift takes are one, and so is a hold that starts or ends that
    # close to the clip's ends: the artist's spans are a few frames off, not a drop and a pick-up
    # (a box drawn in the hands one frame before its hold, read as resting on the floor 1.1 m
    # away, rose into them in six frames). Not where the sketch puts it down elsewhere.
    def in_hands(rest: np.ndarray | None, *frames: int) -> bool:
        """Nothing sketched in a gap, or drawn where the hands hold it at one of its ends."""
        return rest is None or any(drawn_in_hands(rest, fit_pos[f], spec, camera) for f in frames)

    stretches, landings = [], []
    for k, ((start, end), landing) in enumerate(zip(spans, rests[1:])):
        if stretches and start - stretches[-1][1] - 1 < config.lift_frames and in_hands(rests[k], stretches[-1][1], start):
            stretches[-1][1], landings[-1] = end, landing
        else:
            stretches.append([start, end])
            landings.append(landing)
    if stretches[0][0] < config.lift_frames and in_hands(rests[0], spans[0][0]):
        stretches[0][0] = 0
    if n - 1 - stretches[-1][1] < config.lift_frames and in_hands(rests[-1], spans[-1][1]):
        stretches[-1][1] = n - 1
    carried = np.zeros(n, bool)
    for start, end in stretches:
        carried[start:end + 1] = True
    fitted, frames, fit_yaw = held.any(axis=1), np.arange(n), np.unwrap(fit_yaw)
    for axis in range(3):   # carried across the gaps at the pace it was carried, held still at the ends
        fit_pos[carried & ~fitted, axis] = np.interp(frames[carried & ~fitted], frames[fitted], fit_pos[fitted, axis])
    fit_yaw[carried & ~fitted] = np.interp(frames[carried & ~fitted], frames[fitted], fit_yaw[fitted])

    pos, yaw = np.empty((n, 3)), np.empty(n)
    first = stretches[0][0]
    # Before the first hold it rests where it was sketched, else where it is picked up.
    pos[:first] = _grounded(rests[0] if rests[0] is not None else fit_pos[first], config)
    yaw[:first] = fit_yaw[first]
    for (start, end), landing in zip(stretches, landings):
        held_pos = gaussian_filter1d(fit_pos[start:end + 1], config.smooth_sigma, axis=0, mode="nearest")
        held_yaw = gaussian_filter1d(fit_yaw[start:end + 1], config.smooth_sigma, mode="nearest")
        held_pos[:, 1] = np.maximum(held_pos[:, 1], config.rest_height)  # never through the floor
        if start > 0:  # lifted from where it lay, the hands' gap to it closing over a few frames
            w = smoothstep(np.arange(end - start + 1) / max(config.lift_frames, 1))
            held_pos = held_pos + (1.0 - w[:, None]) * (pos[start - 1] - held_pos[0])
            held_pos[:, 1] = np.maximum(held_pos[:, 1], config.rest_height)   # hands coming down onto it
            held_yaw = held_yaw + (1.0 - w) * wrap_angle(yaw[start - 1] - held_yaw[0])
        if end < n - 1:   # put down: the hands lower it onto the ground as they let go (dropped from
            # where they left it, 32 of 64 artist-style put-downs fell 5-39 cm)
            w = smoothstep(np.arange(end - start, -1, -1) / max(config.lift_frames, 1))
            held_pos[:, 1] -= (1.0 - w) * (held_pos[-1, 1] - config.rest_height)
            held_pos[:, 1] = np.maximum(held_pos[:, 1], config.rest_height)
        pos[start:end + 1], yaw[start:end + 1] = held_pos, held_yaw
        # Released, it rests on the ground until the next hold (or the end), sliding to where the
        # sketch puts it down.
        pos[end + 1:] = held_pos[-1]
        if landing is not None:
            w = smoothstep(np.arange(1, n - end) / max(config.lift_frames, 1))[:, None] * (1.0, 0.0, 1.0)
            pos[end + 1:] += w * (landing - pos[end + 1:])
        yaw[end + 1:] = held_yaw[-1]
    # Cleared once more as carried: where a second holder takes hold, the fit jumps (18 cm in a
    # frame), and smoothed it passed through both holders' hips (artist-style penetration within
    # 2 cm on drawings 0, 7777, 500 and a harsher set, 50 scenes x 2 each: 88, 87, 79, 73 -> 89,
    # 90, 82, 77 of 100). Where it rests it keeps the push of the last frame it was carried: put
    # down where the push left it, it stays there (eased back, a box set down slid 2 cm after it).
    push = _clear_of_people(pos, yaw, spec, joints, holding, config.clear_iterations, config.held_clear_frames) - pos
    pos = pos + _carried_forward(push, carried)
    return _rest_clear_of_people(pose_array(pos, yaw), joints, grips, held, spec, config)


def hold_object(joints: np.ndarray, obj_pose: np.ndarray, storyboard: Storyboard,
                config: ContactConfig = ContactConfig()) -> np.ndarray:
    """Object poses that follow the storyboard's holding hands and otherwise rest on the ground.

    joints (N, H, 22, 3) in the storyboard's agent order; obj_pose (N, O, 7) decoded poses in its
    object order (only used for objects nobody holds). Returns (N, O, 7) upright poses.
    """
    joints, obj_pose = np.asarray(joints, float), np.asarray(obj_pose, float)
    n, h = joints.shape[:2]
    table = anchor_table(storyboard)
    out = np.empty_like(obj_pose)
    for o in range(obj_pose.shape[1]):
        held = np.zeros((n, 2 * h), bool)
        grips = np.zeros((n, 2 * h, 3))
        for c in storyboard.contacts:
            if c.object is None or storyboard.object_index(c.object) != o:
                continue
            hand = 2 * storyboard.agent_index(c.agent) + HAND_NAMES.index(c.hand)
            held[c.start:c.end + 1, hand] = True
            grips[c.start:c.end + 1, hand] = table[o, c.anchor]
        bounds = [-1, *(f for span in true_spans(held.any(axis=1)) for f in span), n]   # gaps between the spans
        rests = [sketched_rest(storyboard, o, a + 1, b - 1) for a, b in zip(bounds[::2], bounds[1::2])]
        obj = storyboard.objects[o].id
        drawn = {k.frame: (k.outline.min(axis=0) + k.outline.max(axis=0)) / 2
                 for k in storyboard.object_keys if k.object == obj}
        paths = [(p.start, p.end, base_path(storyboard, p)) for p in storyboard.object_paths if p.object == obj]
        out[:, o] = _hold_one(joints, grips, held, obj_pose[:, o], storyboard.objects[o].spec,
                              config, rests, storyboard.camera, drawn, paths)
    return out


def step_within_reach(joints: np.ndarray, obj_pose: np.ndarray, storyboard: Storyboard,
                      config: ContactConfig = ContactConfig()) -> np.ndarray:
    """People moved (whole bodies, horizontally) until each grip they hold, on the object as
    hold_object fits it to their hands now, lies within `config.reach` of the straight arm from
    the shoulder. The move eases in and out over `blend_frames` around each hold and is zero on
    the person's sketched keyframes, where the sketch says where they stand; away from them it
    grows by at most a metre per `frames_per_metre` frames (a hold drawn right after a key far
    from the object lunged a carrier 76 cm to it and back in a third of a second), easing out of
    the key (key_ease_frames) and into that limit (step_ease_frames). A holder
    whose body is inside an object that others hold too steps back out of it the same way: two
    carriers facing each other across a box, drawn closer than the box is deep, had it 5 cm
    inside a chest, and pushes from the two of them on the box cancel (_clear_of_people).
    joints (N, H, 22, 3), obj_pose (N, O, 7) decoded -> joints (N, H, 22, 3)."""
    joints = np.asarray(joints, float).copy()
    n, h = joints.shape[:2]
    grips = [(c, storyboard.agent_index(c.agent), HAND_NAMES.index(c.hand)) for c in storyboard.contacts
             if c.object is not None]
    if not grips:
        return joints
    k = anchor_table(storyboard).shape[1]
    frames = np.arange(n)
    room = room_from_keys(storyboard, n, 1.0 / config.frames_per_metre, config.key_ease_frames)
    # The object where the hands put it now; refitting it to moved hands would carry it away
    # with the person stepping towards it.
    held = hold_object(joints, obj_pose, storyboard, config)
    anchors = object_anchors(held, storyboard).reshape(n, -1, 3)
    holders: dict[tuple[int, int], np.ndarray] = {}             # (object, person) -> span weight (N,)
    for c, a, _ in grips:
        key = (storyboard.object_index(c.object), a)
        holders[key] = np.maximum(holders.get(key, 0.0), span_weight(n, c.start, c.end, config.blend_frames))
    # The object is fitted to all its holders' hands: of a holder's step back, the others' share parts them.
    shares = {}
    for (o, a), w in holders.items():
        others = sum(v for (p, b), v in holders.items() if p == o and b != a)
        shares[o, a] = np.where(others > 0.5, (w + others) / np.maximum(others, 1e-9), 0.0)
    arms = arm_lengths(joints)                                   # whole-body steps keep them
    start, moved = joints, np.zeros((n, h, 3))
    for _ in range(config.reach_passes):
        need, weight = np.zeros((n, h, 3)), np.zeros((n, h))
        for c, a, side in grips:
            shoulder, arm = joints[:, a, SHOULDERS[side]], arms[:, a, side]
            reach = anchors[np.clip(frames, c.start, c.end), storyboard.object_index(c.object) * k + c.anchor] - shoulder
            across = reach * (1.0, 0.0, 1.0)
            # The horizontal distance at which the grip is `reach` of the arm away (0 when it is
            # farther than that below or above the shoulder: then stand right by it).
            allowed = np.sqrt(np.maximum((config.reach * arm) ** 2 - reach[:, 1] ** 2, 0.0))
            distance = norm(across)
            short = across * (np.maximum(distance - allowed, 0.0) / np.maximum(distance, 1e-9))[:, None]
            w = span_weight(n, c.start, c.end, config.blend_frames) * (distance > allowed)
            need[:, a] += w[:, None] * short
            weight[:, a] += w
        for (o, a), w in holders.items():
            out = _out_of_object(joints[:, a], held[:, o], storyboard.objects[o].spec) * shares[o, a][:, None]
            w = w * np.any(out != 0.0, axis=-1)
            need[:, a] += w[:, None] * out
            weight[:, a] += w
        step = need / np.maximum(weight, 1.0)[..., None]          # the short hands' shortfalls averaged
        moved += gaussian_filter1d(step, config.reach_smoothing, axis=0, mode="nearest")
        length = np.maximum(norm(moved), 1e-9)
        # The share of the step its room allows, eased where it starts to bind (cut off there at
        # once, the body turned back in a frame).
        kept = np.minimum(1.0, room / length)
        if ease := config.step_ease_frames:
            kept = np.minimum(kept, gaussian_filter1d(minimum_filter1d(kept, 2 * ease + 1, axis=0), ease / 2,
                                                      axis=0, mode="nearest"))
        moved *= kept[..., None]
        joints = start + moved[:, :, None]
    return joints


def _out_of_object(joints: np.ndarray, pose: np.ndarray, spec: ObjectSpec) -> np.ndarray:
    """The horizontal move (N, 3) that takes a body (joints (N, 22, 3); its arms aside) out of an
    object at pose (N, 7) as far as its deepest sphere is in, away from the object's centre."""
    points, radii = _body_spheres(joints[:, None])
    depth = np.max(spec.penetration_local(world_to_local(points[:, 0], pose), radii), axis=-1)   # (N,)
    away = normalize((joints[:, 0] - pose[:, :3]) * (1.0, 0.0, 1.0))
    return np.maximum(depth, 0.0)[:, None] * away
