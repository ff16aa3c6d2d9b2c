"""The issue's bad inputs through `sketch2colab generate`: each gives a clear one-line error
(exit 2) or a sensible, finite result; never a traceback or a NaN."""
import json

import numpy as np
import pytest

from engine.camera import StoryboardCamera
from engine.cli import main
from engine.clip import ClipError
from engine.request import Request
from engine.sampling.config import SamplerError
from engine.storyboard import Storyboard

EXAMPLE = "resources/examples/box_handoff.json"


def storyboard(*changes) -> dict:
    """The example as a dict, each change (a function of the dict) applied in place."""
    d = json.loads(open(EXAMPLE).read())
    for change in changes:
        change(d)
    return d


def generate(tmp_path, d: dict, capsys) -> tuple[int, str, np.lib.npyio.NpzFile | None]:
    path = tmp_path / "story.json"
    path.write_text(json.dumps(d))   # json writes NaN as NaN, as a careless exporter would
    out = tmp_path / "motion.npz"
    code = main(["generate", str(path), "-o", str(out), "--steps", "2"])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err, (np.load(out) if code == 0 else None)


def assert_sensible(motion) -> None:
    for name in motion.files:
        if motion[name].dtype.kind == "f":
            assert np.isfinite(motion[name]).all(), name
    assert np.abs(motion["joints"]).max() < 20.0           # people stay in the scene


def test_contradictory_constraints_give_a_finite_compromise(tmp_path, capsys):
    def teleport(d):   # the same agent posed 3 m apart on consecutive frames
        first = dict(d["keyposes"][0], frame=40)
        d["keyposes"] += [first, dict(first, frame=41, points=[None if p is None else [p[0] + 3.0, p[1]]
                                                               for p in first["points"]])]
    code, _, motion = generate(tmp_path, storyboard(teleport), capsys)
    assert code == 0
    assert_sensible(motion)


def test_a_stroke_of_one_point_is_a_clear_error(tmp_path, capsys):
    def one_point(d):
        d["trajectories"][0]["points"] = d["trajectories"][0]["points"][:1]
    code, err, _ = generate(tmp_path, storyboard(one_point), capsys)
    assert code == 2 and "trajectories[0].points" in err and "need at least 2" in err
    assert len(err.strip().splitlines()) == 1


def test_a_storyboard_without_people_is_a_clear_error(tmp_path, capsys):
    code, err, _ = generate(tmp_path, json.loads(Storyboard(length=40).to_json()), capsys)
    assert code == 2 and "agents" in err and len(err.strip().splitlines()) == 1
    with pytest.raises(SamplerError, match="no people"):   # built in code, not read from a file
        Request.build(Storyboard(length=40))


def test_a_keyframe_on_the_last_frame_is_honoured(tmp_path, capsys):
    d = storyboard()
    last = d["length"] - 1
    agent = d["agents"][0]["id"]
    d["keyposes"] = [k for k in d["keyposes"] if not (k["agent"] == agent and k["frame"] == last)]
    pose = next(k for k in d["keyposes"] if k["agent"] == agent)
    d["keyposes"].append(dict(pose, frame=last))
    code, _, motion = generate(tmp_path, d, capsys)
    assert code == 0
    assert_sensible(motion)
    camera = StoryboardCamera(**d["camera"])
    sketched = np.array([p if p is not None else [np.nan, np.nan] for p in pose["points"]])
    placed = ~np.isnan(sketched[:, 0])
    drawn = camera.project(motion["joints"][last, 0])[placed]
    assert np.linalg.norm(drawn - sketched[placed], axis=-1).mean() < 0.05


def test_an_object_with_no_anchors_is_animated_and_exported(tmp_path, capsys):
    def no_grips(d):   # nobody may hold it: contacts on it go too
        d["objects"][0]["anchors"] = []
        d["contacts"] = [c for c in d["contacts"] if "object" not in c]
    path = tmp_path / "story.json"
    path.write_text(json.dumps(storyboard(no_grips)))
    out = tmp_path / "m"
    code = main(["generate", str(path), "-o", str(out / "m.npz"), "--steps", "2", "--bvh-dir", str(out / "bvh"),
                 "--glb", str(out / "s.glb"), "--object-csv", str(out / "o.csv")])
    assert code == 0 and "Traceback" not in capsys.readouterr().err
    assert_sensible(np.load(out / "m.npz"))
    assert (out / "s.glb").stat().st_size > 0 and (out / "o.csv").read_text().count("\n") > 1


def test_a_contact_on_an_object_with_no_anchors_is_a_clear_error(tmp_path, capsys):
    def no_grips(d):
        d["objects"][0]["anchors"] = []
    code, err, _ = generate(tmp_path, storyboard(no_grips), capsys)
    assert code == 2 and "has 0 anchors" in err


@pytest.mark.parametrize("where", ["fps", "camera.elevation_deg", "camera.target.1", "objects.0.size.0",
                                   "keyposes.0.points.0.0", "trajectories.0.points.2.1", "contacts.0.start"])
def test_nan_anywhere_is_a_clear_error(tmp_path, capsys, where):
    def poison(d):
        *parents, last = [int(p) if p.isdigit() else p for p in where.split(".")]
        node = d
        for p in parents:
            node = node[p]
        node[last] = float("nan")
    code, err, _ = generate(tmp_path, storyboard(poison), capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "nan" in err.lower()


def test_sketchify_refuses_clips_it_cannot_draw_in_one_line(tmp_path, capsys):
    from dataclasses import replace

    from engine.synth import synthesize
    clip = synthesize("handoff", 1)
    cases = {"one.npz": clip.slice(0, 1), "zero.npz": clip.slice(0, 0)}
    for name, c in cases.items():
        c.save(tmp_path / name)
    arrays = dict(np.load(tmp_path / "one.npz"))
    arrays["fps"] = np.float32("nan")
    np.savez(tmp_path / "nanfps.npz", **arrays)
    for name in ("one.npz", "zero.npz", "nanfps.npz"):
        assert main(["sketchify", str(tmp_path / name), "-o", str(tmp_path / "s.json")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and name in err[0]
    assert not (tmp_path / "s.json").exists()
    with pytest.raises(ClipError):
        replace(clip, fps=float("inf"))
