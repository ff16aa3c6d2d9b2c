"""Storyboard format: round trips, chi / nu, and one clear line for every broken file."""
import copy
import json
import subprocess
import sys

import numpy as np
import pytest

from engine.camera import StoryboardCamera
from engine.controls import build_controls
from engine.geometry.polylines import resample_polyline
from engine.skeleton import JOINT_INDEX, rest_pose
from engine.storyboard import AGENT_COLORS, Storyboard, StoryboardError, nu

GOOD = {
    "format": "sketch2colab-storyboard", "version": 1, "fps": 20, "length": 60,
    "camera": {"elevation_deg": 20, "azimuth_deg": 35, "target": [0, 0.9, 0]},
    "agents": [{"id": "A"}, {"id": "B"}],
    "objects": [{"id": "box", "type": "box"}],
    "keyposes": [{"agent": "A", "frame": 0, "points": [[0.1, 0.2]] + [None] * 21},
                 {"agent": "B", "frame": 59, "points": [[float(i) / 10, 0.5] for i in range(22)]}],
    "trajectories": [{"agent": "A", "joint": "pelvis", "start": 0, "end": 59,
                      "points": [[0, 0], [1, 0], [1, 1]]}],
    "object_keys": [{"object": "box", "frame": 10, "outline": [[0, 0], [0.4, 0], [0.4, 0.3], [0, 0.3]]}],
    "object_paths": [{"object": "box", "start": 10, "end": 40, "points": [[0, 0], [2, 0]]}],
    "contacts": [{"agent": "A", "hand": "left", "start": 10, "end": 40, "object": "box", "anchor": 1},
                 {"agent": "A", "hand": "right", "start": 45, "end": 50, "other_agent": "B",
                  "other_hand": "right"}],
    "text": "two people carry a box",
}


def broken(path: str, value):
    """GOOD with the field at a dotted path (ints index lists) set to value (None deletes)."""
    d = copy.deepcopy(GOOD)
    *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
    node = d
    for p in parents:
        node = node[p]
    if value is None:
        del node[last]
    else:
        node[last] = value
    return d


def test_round_trip_is_byte_identical(tmp_path):
    sb = Storyboard.from_dict(GOOD)
    path = tmp_path / "s.json"
    sb.save(path)
    again = Storyboard.load(path)
    assert again.to_json() == path.read_text() == sb.to_json()
    assert not (tmp_path / "s.json.tmp").exists()


def test_chi_mask_and_nu():
    sb = Storyboard.from_dict(GOOD)
    chi = sb.chi_mask()
    assert chi.shape == (60, 2, 22)
    assert chi[0, 0, 0] and chi[30, 0, 0] and not chi[30, 0, 1]
    assert chi[59, 1].all() and not chi[30, 1].any()
    assert np.array_equal(chi, build_controls(sb).chi)
    assert nu(0, 60) == 0 and nu(60, 60) == 59 and nu(30, 60) == 30
    assert all(0 <= nu(k, 7) <= 6 for k in np.linspace(0, 7, 50))


def test_holding_marks_each_hand_over_its_contacts():
    held = Storyboard.from_dict(GOOD).holding()
    assert held.shape == (60, 2, 2)
    assert held[10:41, 0, 0].all() and held[45:51, 0, 1].all()
    assert held.sum() == 31 + 6                       # the partner's hand is the other one's contact


def test_retimed_keeps_every_element_at_its_time():
    sb = Storyboard.from_dict(GOOD)                                   # 60 frames at 20 fps
    at30 = sb.retimed(30.0)
    at30.validate()
    assert (at30.fps, at30.length) == (30.0, 90)                      # frames 0..89: 2.97 s, as 0..59 at 20
    assert [k.frame for k in at30.keyposes] == [0, 89]
    assert [(t.start, t.end) for t in at30.trajectories] == [(0, 89)]
    assert [(c.start, c.end) for c in at30.contacts] == [(15, 60), (68, 75)]
    assert at30.object_keys[0].frame == 15 and (at30.object_paths[0].start, at30.object_paths[0].end) == (15, 60)
    assert at30.keyposes[1].points == pytest.approx(sb.keyposes[1].points)
    back = at30.retimed(20.0)
    assert [k.frame for k in back.keyposes] == [0, 59] and back.contacts[0].start == 10
    assert sb.retimed(20.0) is sb
    assert sb.retimed(24.0).length == 72 and sb.retimed(12.0).length == 37   # never shorter in time


def test_controls_resample_strokes_over_their_span():
    c = build_controls(Storyboard.from_dict(GOOD))
    pelvis = c.tr2d[:, 0, JOINT_INDEX["pelvis"]]
    assert np.allclose(pelvis[0], [0, 0]) and np.allclose(pelvis[59], [1, 1])
    steps = np.linalg.norm(np.diff(pelvis, axis=0), axis=1)
    assert np.sum(~np.isclose(steps, 2 / 59)) <= 1  # even in arc length; one chord cuts the corner
    assert c.contact[10:41, 0, 0].all() and (c.contact_anchor[10:41, 0, 0] == 1).all()
    assert np.allclose(c.obj2d[10, 0], [0.2, 0.15, 0.4, 0.3]) and c.obj_mask.sum() == 1
    assert np.allclose(resample_polyline(np.array([[1.0, 2.0], [1.0, 2.0]]), 5), [[1, 2]] * 5)


def test_camera_projection_and_unprojection_agree():
    cam = StoryboardCamera(25, 40, (0.3, 0.9, -0.2))
    p = rest_pose()
    ground = p * [1, 0, 1]
    back = cam.unproject_to_height(cam.project(ground), 0.0)
    assert np.allclose(back, ground)
    basis = cam.basis()
    assert np.allclose(basis @ basis.T, np.eye(3))
    assert cam.project(p)[JOINT_INDEX["head"], 1] > cam.project(p)[0, 1]  # head above pelvis on paper


BROKEN = [
    ("keyposes.0.points", [[0, 0]] * 21, "keyposes[0].points: expected exactly 22 joints, got 21"),
    ("trajectories.0.points", [[0, 0]], "trajectories[0].points: empty stroke"),
    ("trajectories.0.points", [], "trajectories[0].points: empty stroke"),
    ("keyposes.1.frame", 60, "keyposes[1].frame: frame 60 is outside the clip"),
    ("contacts.0.agent", "C", "contacts[0].agent: unknown agent 'C'"),
    ("trajectories.0.joint", "tail", "trajectories[0].joint: unknown joint 'tail'"),
    ("contacts.0.anchor", 5, "contacts[0].anchor: object 'box' has 4 anchors"),
    ("trajectories.0.end", -1, "trajectories[0].end: frame -1 is outside"),
    ("fps", None, "storyboard: missing required field 'fps'"),
    ("version", 7, "version: this program reads storyboard version 1"),
    ("objects.0.type", "piano", "objects[0].type"),
    ("keyposes.0.points", [None] * 22, "keyposes[0].points: no joint is placed"),
    ("agents", [{"id": "A"}, {"id": "A"}], "agents[1].id: duplicate id 'A'"),
    ("length", 1, "length: 1 is out of range (at least 2)"),
    # Numbers no sketch can mean (pixels or millimetres taken for metres, a typo): out of range.
    ("keyposes.1.points.3", [1e6, 0.5], "keyposes[1].points[3][0]: 1e+06 is out of range (at most 100 m)"),
    ("trajectories.0.points.1", [0, -250], "trajectories[0].points[1][1]: -250 is out of range (at least -100 m)"),
    ("camera.target", [0, 0.9, 5000], "camera.target[2]: 5000 is out of range (at most 100 m)"),
    ("objects.0.size", [0.4, 0.3, 0], "objects[0].size[2]: 0 is out of range (more than 0)"),
    ("fps", 1000, "fps: 1000 is out of range (at most 240)"),
    ("length", 3000, "length: 3000 frames at 20 fps is 150 s; clips are at most 120 s"),
    # A colour the views cannot draw (it blanked the 3D view): named, not hex.
    ("agents.0.color", "red", 'agents[0].color: "red" is not a colour; write it #rrggbb'),
    # Too long to check or draw in good time (200000 points froze the app for 9 s).
    ("trajectories.0.points", [[0.0, 0.0]] * 200_000,
     "trajectories[0].points: 200000 points; a stroke has at most 4096"),
]


@pytest.mark.parametrize("path,value,message", BROKEN)
def test_broken_files_name_the_field(path, value, message):
    with pytest.raises(StoryboardError) as e:
        Storyboard.from_dict(broken(path, value))
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


def test_a_short_hex_colour_reads_as_the_long_one():
    assert Storyboard.from_dict(broken("agents.0.color", "#f80")).agents[0].color == "#ff8800"
    assert Storyboard.from_dict(broken("agents.0.color", "#ff880080")).agents[0].color == "#ff880080"
    assert Storyboard.from_dict(broken("agents.0.color", "")).agents[0].color == AGENT_COLORS[0]   # none given


def test_nan_and_infinity_are_rejected():
    text = json.dumps(broken("trajectories.0.points", [[0, float("nan")], [1, 1]]))
    with pytest.raises(StoryboardError, match=r"trajectories\[0\].points\[0\]\[1\]: nan is not a finite"):
        Storyboard.from_json(text)
    with pytest.raises(StoryboardError, match="camera.target.*inf"):
        Storyboard.from_dict(broken("camera.target", [0, float("inf"), 0]))


def test_a_binary_file_is_named_not_a_storyboard_not_by_its_codec(tmp_path):
    path = tmp_path / "photo.json"
    path.write_bytes(b'{"format": "sketch2colab-storyboard"' + bytes(range(128, 256)))
    with pytest.raises(StoryboardError, match=r"not a storyboard \(not UTF-8 text: byte 36 is 0x80\)") as e:
        Storyboard.load(path)
    assert "codec" not in str(e.value)


def test_validate_command_exit_codes(tmp_path):
    good, bad, junk = tmp_path / "good.json", tmp_path / "bad.json", tmp_path / "junk.json"
    good.write_text(json.dumps(GOOD))
    bad.write_text(json.dumps(broken("contacts.0.agent", "Z")))
    junk.write_text('{"format": "sketch2colab-storyboard", "version": ')
    run = lambda f: subprocess.run([sys.executable, "-m", "engine.cli", "validate", str(f)],
                                   capture_output=True, text=True)
    ok = run(good)
    assert ok.returncode == 0 and "ok" in ok.stdout
    for f, needle in ((bad, "contacts[0].agent"), (junk, "malformed JSON"), (tmp_path / "none.json", "cannot read")):
        r = run(f)
        assert r.returncode == 2 and needle in r.stderr
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
