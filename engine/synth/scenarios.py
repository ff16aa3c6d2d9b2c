"""Scenario plans: where two people go, what they hold and when, and how the object moves.

A plan fixes, per frame, each person's ground point and heading, their hand targets and hold
weights, the object's pose and the contact-phase windows; `synthesize` turns it into poses.
Either the object leads (a two-person carry: the object follows a path and each person stands
off one end of it, facing it) or a person leads (a one-person carry: the object sits in front
of them, rigid in their heading frame). Hands hold grips for an exact frame span; they reach
before it and fall back after it.

Scenarios:
  carry_together  approach, grasp the two ends, lift, carry along a curved path, put down, withdraw
  let_go          the same, but the leader lets go midway and the other person finishes alone
                  (boxes and canisters only: nobody carries a table by one end)
  handoff         one person carries a box or canister to the other, who takes it and carries it off
  lift_adjust     a two-person carry that raises and lowers the object on the way
  handshake       two people walk up to each other and hold right hands; the object (O = 1, to keep
                  clip shapes uniform) rests on the floor well away from them
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..objects import ObjectSpec
from .body import Body, make_body
from .props import assign_hands, end_grips, pose_array, random_object, side_grips, world_anchors
from .reach import forward_of, heading_of, wrap_angle, yaw_matrix
from .trajectory import (arc_control, progress, smoothstep, travel, window_weight)

SCENARIOS = ("carry_together", "let_go", "handoff", "lift_adjust", "handshake")


@dataclass
class ScenarioConfig:
    walk_speed: tuple[float, float] = (0.7, 1.1)      # m/s, average over a walk to a spot
    carry_speed: tuple[float, float] = (0.4, 0.75)    # m/s, average while carrying
    standoff: tuple[float, float] = (0.28, 0.33)      # m from grip to ground point (scale 1)
    table_standoff: float = 0.06                      # m more for tables: feet stay clear of the legs
    min_gap: float = 1.0                              # m between two carriers' ground points (scale 1)
    knee_clearance: float = 0.6                       # m a carried object's bottom stays above (scale 1)
    carry_drop: tuple[float, float] = (0.36, 0.46)    # m from standing shoulder down to the grips
    max_turn: float = np.radians(75)                  # heading change over a carry path
    reach_time: float = 0.45                          # s a hand takes to reach a grip
    release_time: float = 0.35                        # s a hand takes to fall back
    window_before: float = 0.15                       # contact window before a grasp (s)
    window_after: float = 0.2                         # contact window after a grasp (s)
    adjust_height: tuple[float, float] = (0.15, 0.3)  # m raised or lowered in lift_adjust
    carried_floor_gap: float = 0.1                    # m a lowered, still carried object keeps
    shake_amplitude: float = 0.03                     # m
    shake_rate: float = 2.5                           # Hz


@dataclass
class PersonPlan:
    body: Body
    ground: np.ndarray        # (N, 3) ground point
    yaw: np.ndarray           # (N,) heading
    hand_target: np.ndarray   # (N, 2, 3) wrist targets (left, right)
    hand_weight: np.ndarray   # (N, 2) 1 while holding, easing in and out around it
    contact: np.ndarray       # (N, 2) bool, the hand is on its target


@dataclass
class ScenePlan:
    scenario: str
    spec: ObjectSpec
    obj_pose: np.ndarray              # (N, 7)
    people: list[PersonPlan]
    windows: list[tuple[float, float]]  # contact-phase spans in seconds


class Track:
    """A ground point and heading over the clip, written segment after segment in time order;
    each segment rewrites the frames from its start to the end of the clip."""

    def __init__(self, times: np.ndarray, ground: np.ndarray, yaw: float):
        self.times = times
        self.ground = np.tile(ground, (len(times), 1))
        self.yaw = np.full(len(times), yaw, dtype=float)

    def here(self, t: float) -> tuple[np.ndarray, float]:
        i = min(int(np.searchsorted(self.times, t)), len(self.times) - 1)
        return self.ground[i].copy(), float(self.yaw[i])

    def walk(self, t0: float, t1: float, control: np.ndarray, face: float | None = None,
             backward: bool = False, turn: float = 0.4) -> None:
        """Walk a curve (control points (C, 3)) over [t0, t1], turning into its heading early and,
        when `face` is given, to that heading late."""
        _, yaw0 = self.here(t0)
        pos, heading = travel(self.times, t0, t1, control)
        if backward:
            heading = heading + np.pi
        p = progress(self.times, t0, t1)
        yaw = yaw0 + np.unwrap(wrap_angle(heading - yaw0)) * smoothstep(p / turn)
        if face is not None:
            yaw = yaw + np.unwrap(wrap_angle(face - yaw)) * smoothstep((p - 1 + turn) / turn)
        self.follow(t0, pos, yaw)

    def follow(self, t0: float, ground: np.ndarray, yaw: np.ndarray) -> None:
        sel = self.times >= t0
        self.ground[sel] = ground[sel] * [1, 0, 1]
        self.yaw[sel] = yaw[sel]


def _timeline(rng: np.random.Generator, seconds: float, parts: list[tuple[str, float, float]]
              ) -> dict[str, tuple[float, float]]:
    """Cut the clip into consecutive spans: (name, fixed seconds, flexible weight). Flexible spans
    share what the fixed ones leave, in randomly jittered proportions."""
    fixed = sum(f for _, f, _ in parts)
    weights = np.array([w for _, _, w in parts]) * rng.uniform(0.75, 1.25, len(parts))
    spare = seconds - fixed
    least = 0.3 * sum(w > 0 for _, _, w in parts)
    if spare < least:
        raise ValueError(f"{seconds:g} s is too short for this scenario (needs at least {fixed + least:.1f} s)")
    spans, t = {}, 0.0
    for (name, f, _), w in zip(parts, weights):
        d = f + spare * w / weights.sum()
        spans[name] = (t, t + d)
        t += d
    return spans


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    return yaw_matrix(np.array(angle)) @ v


def _x_axis(yaw: np.ndarray) -> np.ndarray:
    """World direction (N, 3) of an object's local +X at heading yaw (N,)."""
    return np.stack([np.cos(yaw), np.zeros_like(yaw), -np.sin(yaw)], -1)


def _person(body: Body, track: Track) -> PersonPlan:
    n = len(track.times)
    return PersonPlan(body, track.ground, track.yaw, np.zeros((n, 2, 3)), np.zeros((n, 2)),
                      np.zeros((n, 2), bool))


def _hold(person: PersonPlan, times: np.ndarray, targets: np.ndarray, hands: tuple[int, ...],
          on: float, off: float, cfg: ScenarioConfig) -> None:
    """Hold `targets` (N, len(hands), 3) with `hands` over [on, off]."""
    weight = window_weight(times, on, off, cfg.reach_time, cfg.release_time)
    for i, hand in enumerate(hands):
        person.hand_target[:, hand] = targets[:, i]
        person.hand_weight[:, hand] = weight
        person.contact[:, hand] = (times >= on) & (times <= off)


def _approach(times: np.ndarray, goal: np.ndarray, arrive: np.ndarray, t0: float, t1: float,
              speed: float, angle: float) -> Track:
    """A track that walks up to `goal` over [t0, t1] on a curve arriving along `arrive` (unit),
    from a start behind it in the direction `arrive` turned by `angle`."""
    start = goal - _rotate(arrive, angle) * speed * (t1 - t0)
    control = arc_control(start, goal, arrive, 0.0)
    track = Track(times, start, float(heading_of(control[1] - control[0])))
    track.walk(t0, t1, control)
    return track


def _withdraw(rng: np.random.Generator, track: Track, t0: float, t1: float, away: np.ndarray,
              dist: float, backward: bool, spread: float = 0.5) -> None:
    """Walk `dist` m roughly along `away` (unit), stepping back still facing the same way or
    turning away first."""
    here, _ = track.here(t0)
    goal = here + _rotate(away, rng.uniform(-spread, spread)) * dist
    track.walk(t0, t1, arc_control(here, goal, None, rng.uniform(-0.3, 0.3)), backward=backward,
               turn=0.45)


def _leave(rng: np.random.Generator, track: Track, t0: float, t1: float, away: np.ndarray,
           speed: float) -> None:
    """The usual withdraw: a short step back, or turning away and walking off."""
    backward = bool(rng.random() < 0.4)
    _withdraw(rng, track, t0, t1, away, min(speed * (t1 - t0) * (0.5 if backward else 1.0), 1.5), backward)


def _carry_path(start: np.ndarray, direction: np.ndarray, length: float,
                turn: float) -> np.ndarray:
    """Cubic control points (4, 3) leaving `start` along `direction` and turning by `turn`."""
    end = start + _rotate(direction, turn / 2) * length
    return np.stack([start, start + direction * length / 3,
                     end - _rotate(direction, turn) * length / 3, end])


def _two_person_carry(rng, times, cfg, scenario: str) -> ScenePlan:
    """carry_together, lift_adjust and let_go: the object leads, each person holds one x end."""
    let_go = scenario == "let_go"
    spec = random_object(rng, ("box", "canister") if let_go else ("box", "table", "canister"))
    bodies = [make_body(rng), make_body(rng)]
    seconds = times[-1] + (times[1] - times[0])
    parts = [("lead", 0.0, 0.1), ("approach", 0.0, 1.0), ("reach", 0.4, 0.0), ("grip", 0.15, 0.0),
             ("lift", 0.6, 0.0),
             ("carry", 0.0, 1.3)]
    if let_go:
        parts[-1] = ("carry", 0.0, 0.8)
        parts += [("let_go", 0.3, 0.0), ("clear", 0.5, 0.0), ("finish", 0.0, 0.8)]
    parts += [("lower", 0.6, 0.0), ("release", 0.45, 0.0), ("withdraw", 0.0, 0.5 if let_go else 0.8)]
    span = _timeline(rng, seconds, parts)

    # The object's path: leave along its own x axis (so the people at its ends lead and trail).
    yaw0 = rng.uniform(-np.pi, np.pi)
    start = np.array([rng.uniform(-0.5, 0.5), 0.0, rng.uniform(-0.5, 0.5)])
    lead_end = float(rng.choice([-1.0, 1.0]))
    direction = lead_end * _x_axis(np.array(yaw0))
    turn = rng.uniform(-cfg.max_turn, cfg.max_turn)
    carry_t = span["carry"]
    length = rng.uniform(*cfg.carry_speed) * (carry_t[1] - carry_t[0])
    pos, heading = travel(times, *carry_t, _carry_path(start, direction, length, turn))
    if let_go:
        # Stop, let the leader step aside, then curve away from the side they stepped to.
        side = float(rng.choice([-1.0, 1.0]))
        stop_dir = forward_of(np.array(heading[-1]))
        turn2 = -side * rng.uniform(0.2, 1.0) * cfg.max_turn
        length2 = rng.uniform(*cfg.carry_speed) * (span["finish"][1] - span["finish"][0])
        pos2, heading2 = travel(times, *span["finish"], _carry_path(pos[-1], stop_dir, length2, turn2))
        later = times >= span["finish"][0]
        pos = np.where(later[:, None], pos2, pos)
        heading = np.where(later, heading[-1] + wrap_angle(heading2 - heading[-1]), heading)
    obj_yaw = yaw0 + np.unwrap(wrap_angle(heading - heading_of(direction)))

    grip_x = abs(spec.anchors[0, 0])
    grip_y = spec.anchors[0, 1]
    carry_y = min(b.shoulder_height() - rng.uniform(*cfg.carry_drop) * b.scale for b in bodies)
    lift = max(carry_y - grip_y, 0.05)
    height = lift * (smoothstep(progress(times, *span["lift"])) - smoothstep(progress(times, *span["lower"])))
    if scenario == "lift_adjust":
        amount = rng.uniform(*cfg.adjust_height)
        p = progress(times, *carry_t)
        profile = rng.choice([-1.0, 1.0]) * np.sin(np.pi * rng.integers(1, 3) * p)
        if lift + amount * profile.min() < cfg.carried_floor_gap:
            profile = np.sin(np.pi * p)  # too low to lower it on the way: only raise it
        height += amount * profile
    pose = pose_array(pos + height[:, None] * [0, 1, 0], obj_yaw)
    anchors = world_anchors(spec, pose)
    x_axis = _x_axis(obj_yaw)

    people, ons, offs = [], [], []
    grasp = span["reach"][1]
    release = span["release"][0] + 0.1
    for sx, body in zip((-1.0, 1.0), bodies):
        standoff = (rng.uniform(*cfg.standoff) + cfg.table_standoff * (spec.type == "table")) * body.scale
        standoff = max(standoff, cfg.min_gap * body.scale / 2 - grip_x)  # small objects: keep feet apart
        ground = pos + x_axis * sx * (grip_x + standoff)
        facing = heading_of(-sx * x_axis)
        arrive = span["approach"][1] - rng.uniform(0.0, 0.25)
        track = _approach(times, ground[0], -sx * x_axis[0], span["lead"][1] * rng.random(), arrive,
                          rng.uniform(*cfg.walk_speed), rng.uniform(-1.0, 1.0))
        track.follow(arrive, ground, facing)
        if let_go and sx == lead_end:
            # The leader lets go and walks off ahead and to the side, clear of the object's way on.
            off = span["let_go"][0] + 0.1
            away = _rotate(stop_dir, side * np.pi / 2) + 0.5 * stop_dir
            _withdraw(rng, track, off + 0.15, off + 1.6, away / np.linalg.norm(away),
                      rng.uniform(1.2, 1.5) * body.scale, False, spread=0.15)
        else:
            off = release
            _leave(rng, track, span["withdraw"][0], seconds, sx * x_axis[np.searchsorted(times, off)],
                   rng.uniform(*cfg.walk_speed))
        person = _person(body, track)
        on = grasp + rng.uniform(0.0, 0.1)  # both hold before the lift starts
        grips = end_grips(sx)
        left, right = assign_hands(grips, anchors[np.searchsorted(times, on)], facing[0])
        _hold(person, times, anchors[:, [left, right]], (0, 1), on, off, cfg)
        people.append(person)
        ons.append(on)
        offs.append(off)
    windows = [(min(ons) - cfg.window_before, max(ons) + cfg.window_after)]
    windows += [(o - cfg.window_after, o + cfg.window_before) for o in sorted(set(offs))]
    return ScenePlan(scenario, spec, pose, people, windows)


def _handoff(rng, times, cfg, scenario: str) -> ScenePlan:
    """A carries the object to B at a meeting point; B takes it, turns and carries it off."""
    spec = random_object(rng, ("box", "canister"))
    body_a, body_b = make_body(rng), make_body(rng)
    seconds = times[-1] + (times[1] - times[0])
    span = _timeline(rng, seconds, [("walk", 0.0, 1.2), ("reach", 0.45, 0.0), ("transfer", 0.25, 0.0),
                                    ("turn", 0.3, 0.0), ("away", 0.0, 1.2), ("end", 0.0, 0.3)])
    meet = np.array([rng.uniform(-0.5, 0.5), 0.0, rng.uniform(-0.5, 0.5)])
    f = forward_of(np.array(rng.uniform(-np.pi, np.pi)))       # from A towards B
    depth = abs(spec.anchors[0, 2])
    carry_y = min(b.shoulder_height() - rng.uniform(*cfg.carry_drop) * b.scale for b in (body_a, body_b))
    # Held out in front while walking, so lifted clear of the knees.
    lift = max(carry_y - spec.anchors[0, 1], cfg.knee_clearance * max(body_a.scale, body_b.scale))
    reach_a = depth + rng.uniform(*cfg.standoff) * body_a.scale
    reach_b = depth + rng.uniform(*cfg.standoff) * body_b.scale

    track_a = _approach(times, meet - f * reach_a, f, 0.0, span["walk"][1] - rng.uniform(0, 0.3),
                        rng.uniform(*cfg.carry_speed) * 1.3, rng.uniform(-0.9, 0.9))
    track_b = _approach(times, meet + f * reach_b, -f, rng.uniform(0, 0.3), span["walk"][1] - rng.uniform(0, 0.2),
                        rng.uniform(*cfg.walk_speed), rng.uniform(-0.9, 0.9))
    taken = span["transfer"][1]
    _withdraw(rng, track_a, taken + 0.1, taken + 1.1, -f, rng.uniform(0.5, 0.8), backward=True, spread=0.3)
    away = meet + f * reach_b + _rotate(f, rng.uniform(-0.8, 0.8)) * rng.uniform(*cfg.carry_speed) * (
        span["away"][1] - span["away"][0])
    track_b.walk(span["away"][0], span["away"][1], arc_control(meet + f * reach_b, away, None, rng.uniform(-0.3, 0.3)),
                 turn=0.5)

    def held_by(track: Track, reach: float, flip: float) -> np.ndarray:
        front = forward_of(track.yaw)
        return pose_array(track.ground + front * reach + [0, lift, 0], track.yaw + flip)
    pose = np.where((times < taken)[:, None], held_by(track_a, reach_a, 0.0), held_by(track_b, reach_b, np.pi))
    anchors = world_anchors(spec, pose)

    people = [_person(body_a, track_a), _person(body_b, track_b)]
    t_b = span["reach"][1]
    i_b = np.searchsorted(times, t_b)
    for person, grips, on, off in ((people[0], side_grips(-1.0), 0.0, taken),
                                   (people[1], side_grips(1.0), t_b, seconds)):
        left, right = assign_hands(grips, anchors[i_b], person.yaw[i_b])
        _hold(person, times, anchors[:, [left, right]], (0, 1), on, off, cfg)
    windows = [(t_b - 0.1, taken + 0.1)]  # both hold in between: one window around the transfer
    return ScenePlan(scenario, spec, pose, people, windows)


def _handshake(rng, times, cfg, scenario: str) -> ScenePlan:
    """Two people meet and hold right hands, then part; the object rests well off to one side."""
    bodies = [make_body(rng), make_body(rng)]
    seconds = times[-1] + (times[1] - times[0])
    span = _timeline(rng, seconds, [("lead", 0.0, 0.1), ("approach", 0.0, 1.3), ("reach", 0.45, 0.0),
                                    ("shake", 0.0, 0.9), ("release", 0.3, 0.0), ("withdraw", 0.0, 0.6)])
    centre = np.array([rng.uniform(-0.5, 0.5), 0.0, rng.uniform(-0.5, 0.5)])
    f = forward_of(np.array(rng.uniform(-np.pi, np.pi)))      # from A towards B
    left_a = np.array([f[2], 0.0, -f[0]])
    scale = np.mean([b.scale for b in bodies])
    gap = rng.uniform(0.55, 0.65) * scale
    grip = centre + [0, rng.uniform(1.0, 1.05) * scale, 0]
    # Both stand a little to their own left so that the right hands meet on the midline.
    goals = [centre - f * gap / 2 + left_a * 0.08 * scale, centre + f * gap / 2 - left_a * 0.08 * scale]
    on, off = span["reach"][1], span["release"][0]
    shake = cfg.shake_amplitude * np.sin(2 * np.pi * cfg.shake_rate * (times - on)) * ((times >= on) & (times <= off))

    spec = random_object(rng)
    obj_side = float(rng.choice([-1.0, 1.0]))
    obj_pos = centre + left_a * obj_side * rng.uniform(2.2, 2.8)
    pose = pose_array(np.tile(obj_pos, (len(times), 1)), np.full(len(times), rng.uniform(-np.pi, np.pi)))

    people = []
    for goal, arrive, body, sign in zip(goals, (f, -f), bodies, (-1.0, 1.0)):
        speed = rng.uniform(*cfg.walk_speed)
        # Come in from the side away from the object.
        angle = np.radians(45) * (-obj_side * sign) * rng.uniform(0.2, 1.0)
        track = _approach(times, goal, arrive, span["lead"][1] * rng.random(),
                          span["approach"][1] - rng.uniform(0, 0.2), speed, angle)
        _leave(rng, track, span["withdraw"][0], seconds, -arrive, speed)
        person = _person(body, track)
        target = grip + sign * f * 0.045 + shake[:, None] * [0, 1, 0]
        _hold(person, times, target[:, None], (1,), on, off, cfg)
        people.append(person)
    windows = [(on - cfg.window_before, on + cfg.window_after), (off - cfg.window_after, off + cfg.window_before)]
    return ScenePlan(scenario, spec, pose, people, windows)


_BUILDERS = {"carry_together": _two_person_carry, "let_go": _two_person_carry,
             "lift_adjust": _two_person_carry, "handoff": _handoff, "handshake": _handshake}


def build_plan(scenario: str, rng: np.random.Generator, times: np.ndarray,
               config: ScenarioConfig = ScenarioConfig()) -> ScenePlan:
    """Plan one scene. times: (N,) frame times in seconds."""
    if scenario not in _BUILDERS:
        raise ValueError(f"unknown scenario {scenario!r}; expected one of {', '.join(SCENARIOS)}")
    return _BUILDERS[scenario](rng, times, config, scenario)
