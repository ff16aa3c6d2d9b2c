"""The storyboard: what the artist sketches, its versioned JSON file format, and validation.

Coordinates are sketch-plane metres (see camera.py); frames are 0-based indices into a clip of
`length` frames at `fps`. The JSON Schema is storyboard.schema.json beside this file; the format
is described in docs/storyboard.md. Every problem with a file surfaces as a StoryboardError whose
message names the field, e.g. "keyposes[2].points: expected 22 joints, got 21".
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from .atomic import write_text
from .camera import StoryboardCamera
from .objects import DEFAULT_SIZES, ObjectSpec
from .skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, REST_PELVIS_HEIGHT

FORMAT = "sketch2colab-storyboard"
VERSION = 1
HANDS = ("left", "right")
AGENT_COLORS = ("#e4572e", "#2e86ab", "#76b041", "#9b5de5")
SKETCH_LIMIT_M = 100.0   # |u|, |v| and the camera target's coordinates (the schema's "metres")
MAX_SECONDS = 120.0      # the longest clip the generator is asked for
MAX_FILE_CHARS = 16_000_000  # a storyboard file; the largest real ones are a few hundred kB
MAX_INTEGER = 10 ** 9    # frames, spans and anchors are far below; a longer number is an error
MAX_POLYLINE_POINTS = 4096   # a stroke, floor path or outline; the app keeps strokes' points 4 cm
                             # apart (a 160 m stroke). A file of 200000 points took 9 s to check
POLYLINES = (("trajectories", "points"), ("trajectories", "floor"), ("object_keys", "outline"),
             ("object_paths", "points"))
SPANS = ("trajectories", "object_paths", "contacts")   # the Storyboard lists with start and end frames
FLOOR_PATH_HEIGHT = REST_PELVIS_HEIGHT   # m: the height a floor-plan path is seen at from the camera


class StoryboardError(ValueError):
    """A storyboard that cannot be used; str() is one line naming the offending field."""


@dataclass
class Agent:
    id: str
    name: str = ""
    color: str = ""


@dataclass
class SceneObject:
    id: str
    spec: ObjectSpec = field(default_factory=ObjectSpec)


@dataclass
class Keypose:
    agent: str
    frame: int
    points: np.ndarray  # (22, 2); rows where mask is False are ignored
    mask: np.ndarray    # (22,) bool: which joints the artist placed
    hold: int = 0       # frames after `frame` the pose is held (until the agent's next key at most)
    ease_in: bool = False    # the motion slows into the key (engine.finishing.ease)
    ease_out: bool = False   # the motion starts slowly out of the key (after its hold)
    depth: np.ndarray | None = None   # (22,) m in front of (-) or behind (+) the feet, horizontally
                                      # along the view, where known (a library pose, a turned
                                      # figure: engine.facing); the sketch alone does not say


@dataclass
class Trajectory:
    agent: str
    joint: str
    start: int
    end: int
    points: np.ndarray  # (L, 2) polyline, L >= 2
    floor: np.ndarray | None = None   # (L, 2) world (x, z) of a pelvis path drawn on the floor plan:
                                      # exact where people walk; `points` is it seen from the camera
                                      # at FLOOR_PATH_HEIGHT (floor_path_points)


def floor_path_points(camera: StoryboardCamera, floor: np.ndarray) -> np.ndarray:
    """Sketch-plane points (L, 2) of a floor-plan path (L, 2) of world (x, z), at a standing
    pelvis's height (the sketch plane's v of a walking pelvis)."""
    floor = np.asarray(floor, float)
    return camera.project(np.stack([floor[:, 0], np.full(len(floor), FLOOR_PATH_HEIGHT), floor[:, 1]], -1))


@dataclass
class ObjectKey:
    object: str
    frame: int
    outline: np.ndarray  # (L, 2) closed polygon (a box is its 4 corners)


@dataclass
class ObjectPath:
    object: str
    start: int
    end: int
    points: np.ndarray  # (L, 2)


@dataclass
class Contact:
    """`agent`'s `hand` holds `object`'s anchor, or `other_agent`'s `other_hand`, over [start, end]."""
    agent: str
    hand: str
    start: int
    end: int
    object: str | None = None
    anchor: int = 0
    other_agent: str | None = None
    other_hand: str = "right"


@dataclass
class Storyboard:
    fps: float = 20.0
    length: int = 120
    camera: StoryboardCamera = field(default_factory=StoryboardCamera)
    agents: list[Agent] = field(default_factory=list)
    objects: list[SceneObject] = field(default_factory=list)
    keyposes: list[Keypose] = field(default_factory=list)
    trajectories: list[Trajectory] = field(default_factory=list)
    object_keys: list[ObjectKey] = field(default_factory=list)
    object_paths: list[ObjectPath] = field(default_factory=list)
    contacts: list[Contact] = field(default_factory=list)
    text: str = ""

    # ---- lookups -------------------------------------------------------------------------
    def agent_index(self, agent_id: str) -> int:
        return [a.id for a in self.agents].index(agent_id)

    def object_index(self, object_id: str) -> int:
        return [o.id for o in self.objects].index(object_id)

    def retimed(self, fps: float) -> "Storyboard":
        """The same storyboard at another frame rate: every frame moved to the nearest frame at
        the same time, `length` the fewest frames that last as long (itself at the same rate)."""
        if abs(fps - self.fps) < 1e-9:
            return self
        rate = fps / self.fps
        length = max(2, math.ceil((self.length - 1) * rate - 1e-9) + 1)

        def at(frame: int) -> int:   # the nearest frame, a half frame later (a last frame stays last)
            return min(math.floor(frame * rate + 0.5), length - 1)

        return replace(self, fps=fps, length=length,
                       keyposes=[replace(k, frame=at(k.frame), hold=at(k.frame + k.hold) - at(k.frame))
                                 for k in self.keyposes],
                       object_keys=[replace(k, frame=at(k.frame)) for k in self.object_keys],
                       **{name: [replace(x, start=at(x.start), end=at(x.end)) for x in getattr(self, name)]
                          for name in SPANS})

    def cut_to(self, length: int) -> "Storyboard":
        """The storyboard over `length` frames: what starts past the new end goes, spans that run
        past it end there (a longer clip keeps everything)."""
        last = length - 1
        spans = {name: [replace(x, end=min(x.end, last)) for x in getattr(self, name) if x.start <= last]
                 for name in SPANS}
        return replace(self, length=length, keyposes=[replace(k, hold=min(k.hold, last - k.frame))
                                                      for k in self.keyposes if k.frame <= last],
                       object_keys=[k for k in self.object_keys if k.frame <= last], **spans)

    def keyframes(self) -> list[int]:
        """Sorted frames that carry at least one keypose or object key."""
        return sorted({k.frame for k in self.keyposes} | {k.frame for k in self.object_keys})

    def chi_mask(self) -> np.ndarray:
        """The paper's joint-conditioning indicator chi: (N, H, 22) bool, True where joint j of
        human h is constrained at frame n by a keypose or a trajectory."""
        chi = np.zeros((self.length, len(self.agents), NUM_JOINTS), dtype=bool)
        for k in self.keyposes:
            chi[k.frame, self.agent_index(k.agent)] |= k.mask
        for t in self.trajectories:
            chi[t.start:t.end + 1, self.agent_index(t.agent), JOINT_INDEX[t.joint]] = True
        return chi

    def holding(self, objects_only: bool = False) -> np.ndarray:
        """(N, H, 2) bool: True where hand s (HANDS order) of human h is in a contact at frame n
        (an object contact, with `objects_only`)."""
        held = np.zeros((self.length, len(self.agents), len(HANDS)), dtype=bool)
        for c in self.contacts:
            if c.object is not None or not objects_only:
                held[c.start:c.end + 1, self.agent_index(c.agent), HANDS.index(c.hand)] = True
        return held

    # ---- file format ---------------------------------------------------------------------
    def to_dict(self) -> dict:
        d = {"format": FORMAT, "version": VERSION, "fps": self.fps, "length": self.length,
             "camera": self.camera.to_dict(),
             "agents": [{"id": a.id, "name": a.name, "color": a.color} for a in self.agents],
             "objects": [{"id": o.id, "type": o.spec.type, "size": list(o.spec.size),
                          "anchors": _floats(o.spec.anchors)} for o in self.objects],
             "keyposes": [_keypose_dict(k) for k in self.keyposes],
             "trajectories": [_trajectory_dict(t) for t in self.trajectories],
             "object_keys": [{"object": k.object, "frame": k.frame, "outline": _floats(k.outline)}
                             for k in self.object_keys],
             "object_paths": [{"object": p.object, "start": p.start, "end": p.end,
                               "points": _floats(p.points)} for p in self.object_paths],
             "contacts": [_contact_dict(c) for c in self.contacts]}
        if self.text:
            d["text"] = self.text
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1) + "\n"

    def save(self, path: str | Path) -> None:
        """Written whole or not at all (engine.io.atomic)."""
        write_text(path, self.to_json())

    @classmethod
    def from_dict(cls, d) -> "Storyboard":
        _check_finite(d, "")
        _check_polyline_sizes(d)
        _validate_schema(d)
        sb = cls(fps=float(d["fps"]), length=int(d["length"]), text=d.get("text", ""),
                 camera=StoryboardCamera.from_dict(d["camera"]))
        sb.agents = [Agent(a["id"], a.get("name", ""), _long_hex(a.get("color") or AGENT_COLORS[i % 4]))
                     for i, a in enumerate(d["agents"])]
        for i, o in enumerate(d.get("objects", [])):
            size = tuple(o.get("size", DEFAULT_SIZES[o["type"]]))
            anchors = np.array(o["anchors"], float).reshape(-1, 3) if "anchors" in o else None
            sb.objects.append(SceneObject(o["id"], ObjectSpec(o["type"], size, anchors)))
        for i, k in enumerate(d.get("keyposes", [])):
            mask = np.array([p is not None for p in k["points"]])
            pts = np.array([p if p is not None else (0.0, 0.0) for p in k["points"]], float)
            sb.keyposes.append(Keypose(k["agent"], int(k["frame"]), pts, mask, int(k.get("hold", 0)),
                                       bool(k.get("ease_in", False)), bool(k.get("ease_out", False)),
                                       np.array(k["depth"], float) if "depth" in k else None))
        # The schema takes whole-number floats (5.0) as integers: they become ints here, once.
        for t in d.get("trajectories", []):
            sb.trajectories.append(Trajectory(t["agent"], t["joint"], int(t["start"]), int(t["end"]),
                                              np.array(t["points"], float).reshape(-1, 2),
                                              np.array(t["floor"], float).reshape(-1, 2) if "floor" in t else None))
        for k in d.get("object_keys", []):
            sb.object_keys.append(ObjectKey(k["object"], int(k["frame"]), np.array(k["outline"], float).reshape(-1, 2)))
        for p in d.get("object_paths", []):
            sb.object_paths.append(ObjectPath(p["object"], int(p["start"]), int(p["end"]),
                                              np.array(p["points"], float).reshape(-1, 2)))
        for c in d.get("contacts", []):
            sb.contacts.append(Contact(c["agent"], c["hand"], int(c["start"]), int(c["end"]), c.get("object"),
                                       int(c.get("anchor", 0)), c.get("other_agent"), c.get("other_hand", "right")))
        sb.validate()
        return sb

    @classmethod
    def from_json(cls, text: str) -> "Storyboard":
        if len(text) > MAX_FILE_CHARS:
            raise StoryboardError(f"the file is {len(text) / 1e6:.0f} MB; storyboards are at most "
                                  f"{MAX_FILE_CHARS / 1e6:.0f} MB")
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise StoryboardError(f"malformed JSON at line {e.lineno}, column {e.colno}: {e.msg}") from None
        except RecursionError:
            raise StoryboardError("malformed JSON: nested too deeply") from None
        return cls.from_dict(d)

    @classmethod
    def load(cls, path: str | Path) -> "Storyboard":
        try:
            if Path(path).stat().st_size > 4 * MAX_FILE_CHARS:   # UTF-8: at most 4 bytes a character
                raise StoryboardError(f"cannot read {path}: larger than a storyboard can be")
            text = Path(path).read_text(encoding="utf-8")
        except UnicodeDecodeError as e:   # a binary file: the codec's byte offsets say nothing to a person
            raise StoryboardError(f"cannot read {path}: not a storyboard (not UTF-8 text: byte {e.start} "
                                  f"is 0x{e.object[e.start]:02x})") from None
        except OSError as e:
            raise StoryboardError(f"cannot read {path}: {e}") from None
        return cls.from_json(text)

    # ---- semantic checks -----------------------------------------------------------------
    def validate(self) -> None:
        """Raise StoryboardError for the first inconsistency (references, frames, strokes)."""
        agents = _unique([a.id for a in self.agents], "agents")
        objects = _unique([o.id for o in self.objects], "objects")
        n = self.length
        if n / self.fps > MAX_SECONDS:
            raise StoryboardError(f"length: {n} frames at {self.fps:g} fps is {n / self.fps:.0f} s; "
                                  f"clips are at most {MAX_SECONDS:.0f} s")

        def frame(where: str, f: int) -> None:
            if not 0 <= f < n:
                raise StoryboardError(f"{where}: frame {f} is outside the clip (0..{n - 1})")

        def ref(where: str, value: str, known: list[str], what: str) -> None:
            if value not in known:
                raise StoryboardError(f"{where}: unknown {what} {value!r} (known: {', '.join(known) or 'none'})")

        def span(where: str, start: int, end: int) -> None:
            frame(f"{where}.start", start)
            frame(f"{where}.end", end)
            if end < start:
                raise StoryboardError(f"{where}: end frame {end} is before start frame {start}")

        def stroke(where: str, pts: np.ndarray, minimum: int) -> None:
            if len(pts) < minimum:
                raise StoryboardError(f"{where}: empty stroke ({len(pts)} point{'s' * (len(pts) != 1)}, "
                                      f"need at least {minimum})")

        for i, k in enumerate(self.keyposes):
            w = f"keyposes[{i}]"
            ref(f"{w}.agent", k.agent, agents, "agent")
            frame(f"{w}.frame", k.frame)
            if not 0 <= k.frame + k.hold < n:
                raise StoryboardError(f"{w}.hold: held {k.hold} frames from frame {k.frame}, the pose "
                                      f"runs past the clip's last frame {n - 1}")
            if k.points.shape != (NUM_JOINTS, 2):
                raise StoryboardError(f"{w}.points: expected {NUM_JOINTS} joints, got {len(k.points)}")
            if k.depth is not None and k.depth.shape != (NUM_JOINTS,):
                raise StoryboardError(f"{w}.depth: expected {NUM_JOINTS} depths, got {len(k.depth)}")
            if not k.mask.any():
                raise StoryboardError(f"{w}.points: no joint is placed")
        for i, t in enumerate(self.trajectories):
            w = f"trajectories[{i}]"
            ref(f"{w}.agent", t.agent, agents, "agent")
            ref(f"{w}.joint", t.joint, list(JOINT_NAMES), "joint")
            span(w, t.start, t.end)
            stroke(f"{w}.points", t.points, 2)
            if t.floor is not None and (t.joint != "pelvis" or t.floor.shape != t.points.shape):
                raise StoryboardError(f"{w}.floor: a floor path is the pelvis's, one floor point per stroke point")
        for i, k in enumerate(self.object_keys):
            w = f"object_keys[{i}]"
            ref(f"{w}.object", k.object, objects, "object")
            frame(f"{w}.frame", k.frame)
            stroke(f"{w}.outline", k.outline, 3)
        for i, p in enumerate(self.object_paths):
            w = f"object_paths[{i}]"
            ref(f"{w}.object", p.object, objects, "object")
            span(w, p.start, p.end)
            stroke(f"{w}.points", p.points, 2)
        for i, c in enumerate(self.contacts):
            w = f"contacts[{i}]"
            ref(f"{w}.agent", c.agent, agents, "agent")
            span(w, c.start, c.end)
            if (c.object is None) == (c.other_agent is None):
                raise StoryboardError(f"{w}: give exactly one of 'object' or 'other_agent'")
            if c.object is not None:
                ref(f"{w}.object", c.object, objects, "object")
                count = len(self.objects[self.object_index(c.object)].spec.anchors)
                if not 0 <= c.anchor < count:
                    raise StoryboardError(f"{w}.anchor: object {c.object!r} has {count} anchors, "
                                          f"anchor {c.anchor} does not exist")
            else:
                ref(f"{w}.other_agent", c.other_agent, agents, "agent")
                if c.other_agent == c.agent:
                    raise StoryboardError(f"{w}.other_agent: an agent cannot hold its own hand")


def nu(k: float, length: int) -> int:
    """The paper's keyframe-to-frame map nu(k) = 1 + round(k (N - 1) / N), here 0-based:
    a storyboard location k in [0, N] -> frame index in [0, N - 1]."""
    return int(round(k * (length - 1) / length))


def _floats(a) -> list:
    """Arrays to lists of floats at full precision (JSON writes the shortest text that reads back
    to the same double): a storyboard saved and reopened generates the identical motion (rounded
    to micrometres, a reopened storyboard could generate other motion: a 1 um nudge of a stroke
    point moved joints by up to 22 cm)."""
    return np.asarray(a, float).tolist()


def _keypose_dict(k: Keypose) -> dict:
    d = {"agent": k.agent, "frame": k.frame, "points": [_floats(p) if m else None for p, m in zip(k.points, k.mask)]}
    d.update({name: value for name, value in (("hold", k.hold), ("ease_in", k.ease_in), ("ease_out", k.ease_out))
              if value})       # written only where set: an untimed storyboard reads as before
    if k.depth is not None:
        d["depth"] = _floats(k.depth)
    return d


def _trajectory_dict(t: Trajectory) -> dict:
    d = {"agent": t.agent, "joint": t.joint, "start": t.start, "end": t.end, "points": _floats(t.points)}
    if t.floor is not None:
        d["floor"] = _floats(t.floor)
    return d


def _contact_dict(c: Contact) -> dict:
    d = {"agent": c.agent, "hand": c.hand, "start": c.start, "end": c.end}
    if c.object is not None:
        d.update(object=c.object, anchor=c.anchor)
    else:
        d.update(other_agent=c.other_agent, other_hand=c.other_hand)
    return d


def _unique(ids: list[str], where: str) -> list[str]:
    seen = set()
    for i, x in enumerate(ids):
        if x in seen:
            raise StoryboardError(f"{where}[{i}].id: duplicate id {x!r}")
        seen.add(x)
    return ids


@lru_cache(maxsize=1)
def schema() -> dict:
    return json.loads((Path(__file__).with_name("storyboard.schema.json")).read_text())


def _validate_schema(d) -> None:
    import jsonschema
    if not isinstance(d, dict):
        raise StoryboardError("storyboard: the file must hold a JSON object")
    validator = jsonschema.Draft202012Validator(schema())
    errors = sorted(validator.iter_errors(d), key=lambda e: (len(e.absolute_path), list(map(str, e.absolute_path))))
    if errors:
        raise StoryboardError(_describe(errors[0]))


BOUNDS = {"minimum": "at least", "maximum": "at most", "exclusiveMinimum": "more than"}


def _path(parts) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "storyboard"


def _describe(e) -> str:
    """One readable line for a jsonschema error, without echoing the whole offending value."""
    where = _path(e.absolute_path)
    inst = e.instance
    if e.validator in ("minItems", "maxItems") and isinstance(inst, list):
        what = "joints" if where.endswith(".points") and "keyposes" in where else "items"
        bound = e.validator_value
        expect = f"exactly {bound}" if e.schema.get("minItems") == e.schema.get("maxItems") else (
            f"at least {bound}" if e.validator == "minItems" else f"at most {bound}")
        return f"{where}: expected {expect} {what}, got {len(inst)}"
    if e.validator == "required":
        missing = [r for r in e.validator_value if isinstance(inst, dict) and r not in inst]
        return f"{where}: missing required field {missing[0]!r}"
    if e.validator == "additionalProperties":
        extra = sorted(set(inst) - set(e.schema.get("properties", {})))
        return f"{where}: unknown field {extra[0]!r}"
    if e.validator == "const" and where == "version":
        return f"version: this program reads storyboard version {VERSION}, the file is version {repr(inst)[:40]}"
    if e.validator == "oneOf" and where.startswith("keyposes"):
        if isinstance(inst, list) and e.context:   # a point, but a bad one: say what is wrong with it
            return _describe(min(e.context, key=lambda sub: sub.validator == "type"))
        return f"{where}: a joint is either [u, v] or null"
    if e.validator == "pattern" and where.endswith(".color"):
        return f"{where}: {json.dumps(inst)[:40]} is not a colour; write it #rrggbb (or #rgb, #rrggbbaa)"
    if e.validator in BOUNDS and isinstance(inst, (int, float)):
        unit = " m" if abs(e.validator_value) == SKETCH_LIMIT_M else ""
        return f"{where}: {inst:g} is out of range ({BOUNDS[e.validator]} {e.validator_value:g}{unit})"
    short = json.dumps(inst)[:40] if not isinstance(inst, (dict, list)) else type(inst).__name__
    return f"{where}: {short} is not valid here ({e.validator} {json.dumps(e.validator_value)[:60]})"


def _check_polyline_sizes(d) -> None:
    """A one-line error for a polyline too long to check or draw in good time (before the
    schema, which takes 40 us a point)."""
    if not isinstance(d, dict):
        return
    for group, name in POLYLINES:
        items = d.get(group)
        for i, item in enumerate(items if isinstance(items, list) else []):
            points = item.get(name) if isinstance(item, dict) else None
            if isinstance(points, list) and len(points) > MAX_POLYLINE_POINTS:
                raise StoryboardError(f"{group}[{i}].{name}: {len(points)} points; a stroke has at most "
                                      f"{MAX_POLYLINE_POINTS}")


def _long_hex(color: str) -> str:
    """'#rgb' -> '#rrggbb' (what the views read); the other forms as they are."""
    return "#" + "".join(c * 2 for c in color[1:]) if len(color) == 4 else color


def _check_finite(value, where: str) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise StoryboardError(f"{where or 'storyboard'}: {value} is not a finite number")
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > MAX_INTEGER:
        raise StoryboardError(f"{where or 'storyboard'}: a {len(str(abs(value)))}-digit number is out of range")
    if isinstance(value, dict):
        for k, v in value.items():
            _check_finite(v, f"{where}.{k}" if where else k)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _check_finite(v, f"{where}[{i}]")
