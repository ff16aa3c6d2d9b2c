"""File menu: every motion export run from its menu action (file dialog patched), export errors
as dialogs, and Open Example."""
import csv
import struct

import numpy as np
import pytest
from PySide6.QtWidgets import QFileDialog

from app.examples import EXAMPLES_DIR, list_examples
from engine.clip import MotionClip
from engine.storyboard import Storyboard

from .fakes import sample_storyboard, walking_clip


def file_menu(window):
    return next(a.menu() for a in window.menuBar().actions() if a.text() == "&File")


def menu_action(window, text_start: str):
    return next(a for a in file_menu(window).actions() if a.text().startswith(text_start))


@pytest.fixture
def generated(window):
    """The window holding a finished (fake) generation of the sample storyboard."""
    window.doc.replace_storyboard(sample_storyboard(), None)
    clip = walking_clip(window.doc.storyboard.length, window.doc.storyboard.fps)
    window.doc.set_result([clip], clip.phase)
    return window


@pytest.fixture
def save_dialog(monkeypatch):
    """Answers the save dialog with `answer.path` (None: the person cancels)."""
    class Answer:
        path = None
    answer = Answer()
    monkeypatch.setattr(QFileDialog, "getSaveFileName",
                        lambda *args, **kwargs: (str(answer.path) if answer.path else "", ""))
    return answer


def test_npz_export_round_trips(generated, save_dialog, tmp_path, dialogs):
    save_dialog.path = tmp_path / "motion"            # no suffix typed: the filter's is added
    menu_action(generated, "Export Motion (NPZ)").trigger()
    clip = MotionClip.load(tmp_path / "motion.npz")
    assert clip.num_frames == generated.doc.clip.num_frames and dialogs.errors == []


def test_bvh_export_writes_one_file_per_agent(generated, save_dialog, tmp_path, dialogs):
    save_dialog.path = tmp_path / "take.bvh"
    menu_action(generated, "Export Motion (BVH)").trigger()
    for agent in ("A", "B"):
        assert (tmp_path / f"take_{agent}.bvh").read_text().startswith("HIERARCHY")
    assert dialogs.errors == []
    assert "take_A.bvh" in generated.statusBar().currentMessage()


def test_the_exported_bvh_imports_back_from_the_menu(generated, save_dialog, tmp_path, dialogs, monkeypatch):
    save_dialog.path = tmp_path / "take.bvh"
    menu_action(generated, "Export Motion (BVH)").trigger()
    files = [str(tmp_path / f"take_{agent}.bvh") for agent in ("A", "B")]
    monkeypatch.setattr(QFileDialog, "getOpenFileNames", lambda *args, **kwargs: (files, ""))
    menu_action(generated, "Import Reference Motion (BVH)\u2026").trigger()   # a file dialog, then the files
    assert dialogs.errors == [] and generated.doc.reference is not None
    assert generated.doc.reference.num_humans == 2 and generated.doc.reference.num_frames == generated.doc.clip.num_frames


def test_the_3d_view_exports_to_a_png_even_when_the_name_has_no_suffix(generated, save_dialog, tmp_path, dialogs):
    save_dialog.path = tmp_path / "view"
    menu_action(generated, "Export 3D View").trigger()
    assert (tmp_path / "view.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and dialogs.errors == []


def test_gltf_export_writes_a_glb(generated, save_dialog, tmp_path, dialogs):
    save_dialog.path = tmp_path / "scene.glb"
    action = menu_action(generated, "Export Scene (glTF)")
    assert action.isEnabled()
    action.trigger()
    data = (tmp_path / "scene.glb").read_bytes()
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert magic == b"glTF" and version == 2 and length == len(data)
    assert dialogs.errors == []


def test_object_path_export_writes_a_row_per_frame(generated, save_dialog, tmp_path, dialogs):
    save_dialog.path = tmp_path / "box.csv"
    menu_action(generated, "Export Object Path (CSV)").trigger()
    with (tmp_path / "box.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0][:4] == ["frame", "time_s", "object", "x"]
    assert len(rows) == 1 + generated.doc.clip.num_frames * generated.doc.clip.num_objects
    assert dialogs.errors == []


def test_export_errors_are_dialogs_and_keep_the_document(generated, save_dialog, tmp_path, dialogs):
    before = generated.doc.storyboard.to_json()
    clip = generated.doc.clip
    save_dialog.path = tmp_path / "missing_folder" / "scene.glb"
    menu_action(generated, "Export Scene (glTF)").trigger()
    assert len(dialogs.errors) == 1 and "scene.glb" in dialogs.errors[0] and "\n" not in dialogs.errors[0]
    assert generated.doc.storyboard.to_json() == before and generated.doc.clip is clip


def test_exports_without_motion_say_generate_first(window, save_dialog, tmp_path, dialogs):
    save_dialog.path = tmp_path / "x"
    for name in ("Export Motion (NPZ)", "Export Motion (BVH)", "Export Scene (glTF)", "Export Object Path"):
        menu_action(window, name).trigger()
    assert len(dialogs.errors) == 4 and all("generate first" in e for e in dialogs.errors)
    assert list(tmp_path.glob("x*")) == []


def test_cancelled_dialog_writes_nothing(generated, save_dialog, tmp_path, dialogs):
    menu_action(generated, "Export Scene (glTF)").trigger()
    assert list(tmp_path.glob("*.glb")) == []
    assert dialogs.errors == []


def test_open_example_menu_lists_the_examples_by_their_text(window, dialogs):
    examples = list_examples()
    assert len(examples) >= 4
    menu = window.examples_menu
    assert [a.text() for a in menu.actions()] == [e.label for e in examples]
    handoff = next(a for a in menu.actions() if a.toolTip() == "box_handoff.json")
    assert handoff.text() == "One person hands a box to the other"

    handoff.trigger()
    expected = Storyboard.load(EXAMPLES_DIR / "box_handoff.json")
    assert window.doc.storyboard.to_json() == expected.to_json()
    # An untitled copy: saving asks for a place, so the shipped example stays as it is.
    assert window.doc.path is None and not window.doc.dirty
    assert dialogs.errors == []
    # The canvas frames the whole sketch.
    sketch = np.concatenate([k.points[k.mask] for k in expected.keyposes] + [t.points for t in expected.trajectories]
                            + [k.outline for k in expected.object_keys])
    px = window.canvas.to_px(sketch)
    assert (px >= 0).all() and (px[:, 0] <= window.canvas.width()).all() and (px[:, 1] <= window.canvas.height()).all()


def test_save_adds_json_so_that_open_shows_the_file(window, save_dialog, tmp_path, dialogs):
    window.doc.replace_storyboard(sample_storyboard(), None)
    save_dialog.path = tmp_path / "handoff"
    menu_action(window, "Save &As").trigger()
    assert Storyboard.load(tmp_path / "handoff.json").length == window.doc.storyboard.length
    assert not (tmp_path / "handoff").exists() and window.doc.path == tmp_path / "handoff.json"
