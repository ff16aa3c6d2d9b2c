"""Starting points for new keyposes: the standing template (engine.poses), a copy of the
previous keyframe, a pose of the library or a copied pose placed where the figure stands (carried
along the person's pelvis stroke from the key before: stamped at a stroke's end frame, a pose
stood back at the previous key and left the stroke's end behind); which
way a keypose faces. A library pose that reaches for something is stamped reaching it: the grips
of an object lying on the floor, a partner's hands, the grips at the carrier's end of an object
carried with others (the stamp knows the object's grips and the people's depths in 3D, which the
artist's 2D drag cannot show)."""
from __future__ import annotations

import numpy as np

from engine.facing import depth_of, facing, lift
from engine.finishing.warp import LEVEL
from engine.finishing.held import sketched_rest
from engine.controls import stroke_per_frame
from engine.poses import REACHES_FOR, hands_placed, library_pose, library_pose_2d, reach_of, standing_pose_2d
from engine.skeleton import FEET, HANDS, JOINT_INDEX, NUM_JOINTS
from engine.storyboard import Keypose, Storyboard, Trajectory
from engine.synth.reach import heading_of, yaw_matrix


def previous_keypose(sb: Storyboard, agent: str, frame: int) -> Keypose | None:
    """The agent's latest keypose strictly before `frame`."""
    earlier = [k for k in sb.keyposes if k.agent == agent and k.frame < frame]
    return max(earlier, key=lambda k: k.frame) if earlier else None


def key_at_or_before(sb: Storyboard, agent: str, frame: int) -> Keypose | None:
    """The agent's keypose at `frame`, else its latest one before it."""
    return next((k for k in sb.keyposes if k.agent == agent and k.frame == frame), None) or previous_keypose(sb, agent, frame)


def new_keypose(sb: Storyboard, agent: str, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """(points (22, 2), mask (22,)) for a keypose added at `frame`: the previous keyframe's pose
    where the agent's pelvis stroke takes it by then, or a standing figure placed apart from the
    other agents (its pelvis on the stroke where one spans the frame)."""
    previous = previous_keypose(sb, agent, frame)
    if previous is not None:
        return previous.points + carried_along(sb, agent, previous, frame), previous.mask.copy()
    offset = 0.8 * (sb.agent_index(agent) - (len(sb.agents) - 1) / 2)
    points = standing_pose_2d(sb.camera) + (offset, 0.0)
    stroke = _pelvis_stroke(sb, agent, frame)
    if stroke is not None:
        points += stroke_per_frame(stroke)[frame - stroke.start] - points[0]
    return points, np.ones(len(points), bool)


def carried_along(sb: Storyboard, agent: str, since: Keypose | None, frame: int) -> np.ndarray:
    """How far (2,) on the sketch the agent's pelvis stroke takes them from key `since` to `frame`
    (from the stroke's start, where the key comes before it); zero where no stroke spans `frame`."""
    stroke = _pelvis_stroke(sb, agent, frame)
    if since is None or stroke is None:
        return np.zeros(2)
    along = stroke_per_frame(stroke)
    return along[frame - stroke.start] - along[max(since.frame, stroke.start) - stroke.start]


def _pelvis_stroke(sb: Storyboard, agent: str, frame: int) -> Trajectory | None:
    """The agent's pelvis stroke that spans `frame`, if any."""
    return next((tr for tr in sb.trajectories
                 if tr.agent == agent and tr.joint == "pelvis" and tr.start <= frame <= tr.end), None)


def stamped_pose(sb: Storyboard, agent: str, frame: int, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (22, 2), mask (22,), depth (22,)) of library pose `name` for the agent at `frame`,
    standing where the agent stands (see `placed_pose`). A pose that reaches for a person or an
    object (engine.poses.REACHES_FOR) reaches for the nearest one drawn then (`_aim`); any other,
    and a carry the contacts say the agent holds alone, faces the way the agent walks to this key
    (or from it, at the first), else the way their keypose before it faces (the library's poses all face +Z: a
    giver on the left held the box out away from the taker, a carrier turned back on the box at
    every key; facing the way the hand over before it faced, a taker walked the box away
    backwards; facing the way they walk, two carriers of one box turned their backs on it)."""
    mask = np.ones(NUM_JOINTS, bool)
    points, _ = placed_pose(sb, agent, frame, library_pose_2d(name, sb.camera), mask)
    yaw = hands = None
    if abs(sb.camera.basis()[2][1]) > LEVEL:   # a level camera does not say where on the floor anyone is
        feet = _on_floor(points, sb)
        yaw, hands = _aim(sb, agent, frame, name, points, feet)
        if yaw is None and (REACHES_FOR.get(name) is None or _holders(sb, agent, frame) == [agent]):
            yaw = _walking_facing(sb, agent, frame, feet)
    if yaw is None:
        yaw = _previous_facing(sb, agent, frame)
    if hands is not None:   # from the floor into the library pose's own place
        hands = hands - _to_stand_at(library_pose(name, yaw), feet)
    reach = PICK_UP_REACH if REACHES_FOR.get(name) == "resting object" else 1.0
    points, mask = placed_pose(sb, agent, frame, library_pose_2d(name, sb.camera, yaw, hands, reach), mask)
    return points, mask, depth_of(library_pose(name, yaw, hands, reach), sb.camera)


def _aim(sb: Storyboard, agent: str, frame: int, name: str, points: np.ndarray, feet: np.ndarray
         ) -> tuple[float | None, np.ndarray | None]:
    """(yaw, world wrist targets (2, 3) or None) that turn library pose `name`, for the figure
    `points` (22, 2) standing at `feet` (3,) on the floor, towards the nearest of what it reaches
    for: a pick-up, with its hands on the grips of the object where it rests then; a hand over,
    with its hands held out to meet the other person's halfway (at arm's length, a giver's and
    a taker's met 20 cm past each other and the box went into the giver); a carry, to the left
    or right on the sketch, at an object drawn at `frame`, else at the others who hold what the
    agent holds then, with its hands on their end of it. (None, None) where there is none."""
    reaches = REACHES_FOR.get(name)
    if reaches == "resting object":
        held = [g for g in (_resting_grips(sb, o, frame) for o in range(len(sb.objects))) if g is not None and len(g)]
        if not held:
            return None, None
        grips = min(held, key=lambda g: float(np.linalg.norm((g.mean(0) - feet)[[0, 2]])))
        across = _across(sb, (grips.mean(0) - feet) @ sb.camera.basis()[0], name)
        # Square to the sketch, as people who lift something between them stand; turned to it where
        # that does not reach it (a box drawn well nearer the camera); neither reaching, as the library has it.
        for yaw in (across, float(heading_of(grips.mean(0) - feet) - heading_of(reach_of(name)))):
            hands = _hands_on(grips, library_pose(name, yaw), feet, lifted=name == "lift")
            if _reaches(name, yaw, hands, feet):
                return yaw, hands
        return across, None
    if reaches == "person":
        others = [key_at_or_before(sb, a.id, frame) for a in sb.agents if a.id != agent]
        others = [k for k in others if k is not None and k.mask[list(FEET)].all() and k.mask[0]]
        if not others:
            return None, None
        other = min(others, key=lambda k: float(np.linalg.norm(_on_floor(k.points, sb, k.depth) - feet)))
        yaw = float(heading_of(_on_floor(other.points, sb, other.depth) - feet) - heading_of(reach_of(name)))
        return yaw, _meeting_hands(name, yaw, feet, lift(other.points, sb.camera, other.depth)[0])
    places = [key.outline.mean(0) for key in sb.object_keys if key.frame == frame] if reaches == "object" else []
    if places:
        nearest = min(places, key=lambda p: float(np.linalg.norm(p - points[0])))
        return _across(sb, nearest[0] - points[0][0], name), None
    others = [key_at_or_before(sb, a, frame) for a in _holders(sb, agent, frame) if a != agent] if reaches == "object" else []
    others = [k for k in others if k is not None and k.mask[0] and k.mask[list(FEET)].all()]
    if not others:
        return None, None
    # Carried with others: facing them across it, the hands on its grips at their end of it.
    other = min(others, key=lambda k: float(np.linalg.norm(k.points[0] - points[0])))
    yaw = _across(sb, other.points[0][0] - points[0][0], name)
    pose = library_pose(name, yaw)
    held = next(c.object for c in sb.contacts if c.agent == agent and c.object and c.start <= frame <= c.end)
    grips = _carried_between(sb.objects[sb.object_index(held)].spec, pose + _to_stand_at(pose, feet),
                             lift(other.points, sb.camera, other.depth)[0])
    return yaw, _hands_on(grips, pose, feet, lifted=False)


def _holders(sb: Storyboard, agent: str, frame: int) -> list[str]:
    """Everyone holding, at `frame`, an object `agent` holds then (the contacts drawn so far)."""
    held = {c.object for c in sb.contacts if c.agent == agent and c.object and c.start <= frame <= c.end}
    return sorted({c.agent for c in sb.contacts if c.object in held and c.start <= frame <= c.end})


def _across(sb: Storyboard, towards: float, name: str) -> float:
    """The yaw that turns library pose `name`'s reach square to the sketch's right (`towards` > 0)
    or left: people facing each other across the sketch stay so when they carry on."""
    return float(heading_of((np.sign(towards) or 1.0) * sb.camera.basis()[0]) - heading_of(reach_of(name)))


# Of an arm's length: a pick-up reaches its grips with the elbows bent (straight, at the stamp's
# full reach, a person's arms shorter than the library's fell 9-15 cm short of a box's grips).
PICK_UP_REACH = 0.9
PUT_DOWN = 5      # frames from a hold's end at which a pick-up pose puts the object down
HAND_GAP = {"hand over": 0.15, "shake hands": 0.05}   # m between two people's hands that meet
FURTHER = 0.1     # m beyond its own reach that a pose's hands go to meet someone's


def _meeting_hands(name: str, yaw: float, feet: np.ndarray, other: np.ndarray) -> np.ndarray:
    """World wrist targets (2, 3) of library pose `name` turned by `yaw` at `feet`: the hands it
    places held out to meet, halfway, hands held out from the pelvis `other` (3,), where that is at
    most a little further than the pose's own reach (a handshake's hands stopped 20 cm short); as
    the pose holds them where the other is further."""
    pose = library_pose(name, yaw)
    pose = pose + _to_stand_at(pose, feet)
    line = (other - pose[0]) * (1.0, 0.0, 1.0)
    ahead = line / max(float(np.linalg.norm(line)), 1e-9)
    placed = hands_placed(name)
    out = (pose[placed] - pose[0]) @ ahead                             # how far forward each hand is
    meet = max(float(np.linalg.norm(line)) / 2 - HAND_GAP[name] / 2, 0.2)
    if meet <= out.max() + FURTHER:                                    # else too far apart to meet
        pose[placed] += (meet - out)[:, None] * ahead
    return pose[list(HANDS)]


def _reaches(name: str, yaw: float, hands: np.ndarray, feet: np.ndarray, within: float = 0.03) -> bool:
    """Whether library pose `name` turned by `yaw` and standing at `feet` gets its wrists within
    `within` m of the world targets `hands` (2, 3)."""
    pose = library_pose(name, yaw, hands - _to_stand_at(library_pose(name, yaw), feet), PICK_UP_REACH)
    return bool(np.linalg.norm(pose[list(HANDS)] + _to_stand_at(pose, feet) - hands, axis=-1).max() <= within)


def _carried_between(spec, pose: np.ndarray, other: np.ndarray) -> np.ndarray:
    """World grips (K, 3) of an object (spec: engine.objects.ObjectSpec) carried between the pose
    (22, 3) and another holder's pelvis `other` (3,): level, midway, its grips' ends towards the
    holders, at the pose's hand height (two carry keys' hands 5-10 cm from where a rigid table
    between them could be)."""
    line = (other - pose[0]) * (1.0, 0.0, 1.0)
    yaw = np.arctan2(-line[2], line[0])                    # the object's +x (its grips' ends) along the line
    base = (pose[0] + other) / 2 * (1.0, 0.0, 1.0)
    base[1] = pose[list(HANDS), 1].mean() - spec.anchors[:, 1].mean()
    return base + spec.anchors @ yaw_matrix(np.array(yaw)).T


def _hands_on(grips: np.ndarray, pose: np.ndarray, feet: np.ndarray, lifted: bool) -> np.ndarray:
    """World wrist targets (2, 3): the two of an object's grips (K, 3) on the side nearest the pose
    (22, 3) standing at `feet` (one carrier of two takes the end before them, not both ends), the
    left hand on the left one; at the pose's own wrist height where the object is `lifted` off
    the floor."""
    wrists = pose[list(HANDS)] + _to_stand_at(pose, feet)
    left = pose[JOINT_INDEX["l_hip"]] - pose[JOINT_INDEX["r_hip"]]
    pairs = [(i, j) for i in range(len(grips)) for j in range(len(grips)) if i != j and (grips[i] - grips[j]) @ left >= 0]

    def farness(pair):   # from the feet, then (a tenth as much) from the pose's own wrists
        i, j = pair
        return float(np.linalg.norm(((grips[i] + grips[j]) / 2 - feet)[[0, 2]])
                     + 0.1 * (np.linalg.norm(grips[i] - wrists[0]) + np.linalg.norm(grips[j] - wrists[1])))

    hands = grips[list(min(pairs or [(0, min(1, len(grips) - 1))], key=farness))].copy()
    if lifted:
        hands[:, 1] = np.maximum(hands[:, 1], wrists[:, 1])
    return hands


def _resting_grips(sb: Storyboard, o: int, frame: int) -> np.ndarray | None:
    """World grips (K, 3) of object o on the floor where a pick-up or put-down at `frame` finds it,
    as finishing places it (engine.finishing.held.sketched_rest): at the end of a hold (within
    PUT_DOWN frames), where the sketch puts it down after; in someone's hands then, None (it is
    not on the floor); else drawn at `frame`, or where it rests since its last hold, or where its
    first key draws it. Square to the sketch, as the contact tool shows its grips
    (engine.grips.anchors_in_sketch). None without keys."""
    obj = sb.objects[o].id
    holds = sorted((c.start, c.end) for c in sb.contacts if c.object == obj)
    ending = [end for start, end in holds if start < frame and abs(end - frame) <= PUT_DOWN]
    if ending:   # a put-down: where it lands
        after = max(ending)
        place = sketched_rest(sb, o, after + 1, min((s for s, _ in holds if s > after), default=sb.length) - 1)
    elif any(start < frame <= end for start, end in holds):
        return None
    elif any(k.object == obj and k.frame == frame for k in sb.object_keys):
        place = sketched_rest(sb, o, frame, frame)
    else:
        place = sketched_rest(sb, o, 1 + max((end for _, end in holds if end < frame), default=-1), frame)
    if place is None:
        first = min((k.frame for k in sb.object_keys if k.object == obj), default=None)
        if first is None:
            return None
        place = sketched_rest(sb, o, first, first)
    return place + sb.objects[o].spec.anchors @ yaw_matrix(np.array(np.deg2rad(sb.camera.azimuth_deg))).T


def _to_stand_at(pose: np.ndarray, feet: np.ndarray) -> np.ndarray:
    """The horizontal move (3,) that stands a 3D pose (22, 3) with its feet at `feet` (3,)."""
    return (feet - pose[list(FEET)].mean(0)) * (1.0, 0.0, 1.0)


def _on_floor(points: np.ndarray, sb: Storyboard, depth: np.ndarray | None = None) -> np.ndarray:
    """The world point (3,) on the floor under a figure's (22, 2) feet."""
    return lift(points, sb.camera, depth)[list(FEET)].mean(0) * (1.0, 0.0, 1.0)


WALK = 0.8   # m between two keys' feet: a person who goes further walks there facing the way (a step
             # back after a handshake, turned, popped the knees 9-18 cm)


def _walking_facing(sb: Storyboard, agent: str, frame: int, feet: np.ndarray) -> float | None:
    """The yaw of someone standing at `feet` (3,) at `frame` who walked there from their key
    before (further than WALK), or, at their first key, walks on to the next; else None."""
    before = previous_keypose(sb, agent, frame)
    later = [k for k in sb.keyposes if k.agent == agent and k.frame > frame]
    for key, sign in ((before, 1.0), (min(later, key=lambda k: k.frame) if later and before is None else None, -1.0)):
        if key is not None and key.mask[list(FEET)].all():
            way = sign * (feet - _on_floor(key.points, sb, key.depth))
            if np.linalg.norm(way) > WALK:
                return float(heading_of(way))
    return None


def _previous_facing(sb: Storyboard, agent: str, frame: int) -> float:
    """The yaw of the agent's keypose before `frame` where its depths say it (a stamped or turned
    pose), else 0."""
    key = previous_keypose(sb, agent, frame)
    if key is None or key.depth is None or not key.mask[TURNABLE].all():
        return 0.0
    return facing(lift(key.points, sb.camera, key.depth))


def placed_pose(sb: Storyboard, agent: str, frame: int, points: np.ndarray, mask: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """A pose (points (22, 2), mask (22,)) moved to where the agent stands at `frame`: its feet on
    the feet of the agent's keypose there (or the one before, carried along the pelvis stroke),
    else its pelvis on that pelvis, else where a new keypose would go. A pose with neither feet
    nor pelvis is left where it is."""
    here = key_at_or_before(sb, agent, frame)
    walked = carried_along(sb, agent, here, frame)
    feet = list(FEET)
    if here is not None and here.mask[feet].all() and mask[feet].all():
        shift = here.points[feet].mean(0) + walked - points[feet].mean(0)
    elif mask[0]:
        target = here.points[0] + walked if here is not None and here.mask[0] else new_keypose(sb, agent, frame)[0][0]
        shift = target - points[0]
    else:
        shift = np.zeros(2)
    return points + shift, mask.copy()


TURNABLE = list(FEET) + [JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]]   # joints a facing is read from


def known_depth(doc, key: Keypose) -> np.ndarray | None:
    """The key's depths (engine.facing): its own, else the shown motion's at its frame, else None."""
    if key.depth is not None or not doc.clips:
        return key.depth
    joints = doc.clips[min(doc.variation, len(doc.clips) - 1)].joints
    h = doc.storyboard.agent_index(key.agent)
    if h >= joints.shape[1]:
        return None
    return depth_of(np.asarray(joints[min(key.frame, len(joints) - 1), h], float), doc.storyboard.camera)


def key_facing(doc, key: Keypose, points: np.ndarray | None = None) -> tuple[float, np.ndarray, bool] | None:
    """(yaw, world (3,) point under the feet, whether its depth is a guess) of a keypose (its
    points, or `points` (22, 2) while dragged); None when its feet or hips are not placed."""
    if not key.mask[TURNABLE].all():
        return None
    depth = known_depth(doc, key)
    points = key.points if points is None else points
    return facing(lift(points, doc.storyboard.camera, depth)), _on_floor(points, doc.storyboard, depth), depth is None
