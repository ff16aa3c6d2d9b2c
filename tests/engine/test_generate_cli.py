"""`sketch2colab generate` end to end: outputs in a folder that does not exist yet, every export
option, one JSON summary line, and a clear exit 2 for an export the storyboard cannot have."""
import json

from engine.cli import main


def test_generate_writes_every_export(tmp_path, capsys):
    out = tmp_path / "new" / "folder"
    code = main(["generate", "resources/examples/box_handoff.json", "-o", str(out / "m.npz"), "--steps", "2",
                 "--bvh-dir", str(out / "bvh"), "--glb", str(out / "s.glb"), "--object-csv", str(out / "o.csv")])
    assert code == 0
    assert {p.name for p in out.iterdir()} == {"m.npz", "bvh", "s.glb", "o.csv"}
    assert sorted(p.name for p in (out / "bvh").iterdir()) == ["person_A.bvh", "person_B.bvh"]
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["network_evals"] == 4 and summary["K2D"] >= 0


def test_export_the_storyboard_cannot_have_is_a_clear_error(tmp_path, capsys):
    code = main(["generate", "resources/examples/handshake.json", "-o", str(tmp_path / "h.npz"), "--steps", "1",
                 "--object-csv", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "no object" in err and "Traceback" not in err


def test_steady_generation_runs(tmp_path, capsys):
    code = main(["generate", "resources/examples/handshake.json", "-o", str(tmp_path / "h.npz"), "--steps", "3",
                 "--steady"])
    assert code == 0 and (tmp_path / "h.npz").exists()
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["network_evals"] == 6
