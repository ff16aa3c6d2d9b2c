"""The document model and its commands, without any widget."""
import numpy as np
import pytest

from app import commands as cmd
from app.document import Document
from app.strokes import clean_stroke, splice
from engine.storyboard import MAX_POLYLINE_POINTS, Contact, Storyboard, Trajectory

from .fakes import sample_storyboard


def snapshot(doc: Document) -> str:
    return doc.storyboard.to_json()


def check_undo_redo(doc: Document, command) -> None:
    """Pushing, undoing and redoing `command` changes, restores and re-applies the storyboard."""
    before = snapshot(doc)
    doc.undo_stack.push(command)
    after = snapshot(doc)
    assert after != before
    doc.storyboard.validate()
    doc.undo_stack.undo()
    assert snapshot(doc) == before
    doc.undo_stack.redo()
    assert snapshot(doc) == after


@pytest.fixture
def doc():
    return Document(sample_storyboard())


def test_every_command_undoes_and_redoes(doc):
    sb = doc.storyboard
    k = sb.keyposes[0]
    line = np.array([[0.0, 0.0], [0.5, 0.2], [1.0, 0.0]])
    edits = [
        cmd.SetKeypose(doc, "A", 10, k.points + 0.1, k.mask),
        cmd.MoveKeyposeJoint(doc, "A", 0, 20, (0.3, 0.4)),
        cmd.DeleteKeyposeJoint(doc, "A", 0, 20),
        cmd.MirrorKeypose(doc, "B", 60),
        cmd.DeleteKeypose(doc, "B", 0),
        cmd.RetimeKeyframe(doc, "agent", "A", 60, 70),
        cmd.RetimeKeyframe(doc, "object", "box1", 60, 50),
        cmd.AddStroke(doc, "trajectories", Trajectory("B", "r_wrist", 10, 40, line)),
        cmd.ReplaceStroke(doc, "trajectories", 0, Trajectory("A", "pelvis", 0, 119, line)),
        cmd.EraseStroke(doc, "object_paths", 0),
        cmd.SetObjectKey(doc, "box1", 90, line),
        cmd.SetObjectKey(doc, "table1", 20, line, kind="table"),
        cmd.MoveObjectKey(doc, 0, (0.2, 0.0)),
        cmd.DeleteObjectKey(doc, 0),
        cmd.SetObjectSpec(doc, "box1", "canister", (0.3, 0.5, 0.3)),
        cmd.AddContact(doc, Contact("A", "left", 5, 15, other_agent="B", other_hand="right")),
        cmd.DeleteContact(doc, 1),
    ]
    for edit in edits:
        check_undo_redo(doc, edit)
    assert doc.undo_stack.count() == len(edits)
    assert doc.dirty
    while doc.undo_stack.canUndo():
        doc.undo_stack.undo()
    assert snapshot(doc) == sample_storyboard().to_json()
    assert not doc.dirty


def test_mirror_swaps_sides_and_reflects(doc):
    k = cmd.find_keypose(doc.storyboard, "A", 60)
    before = k.points.copy()
    doc.undo_stack.push(cmd.MirrorKeypose(doc, "A", 60))
    after = cmd.find_keypose(doc.storyboard, "A", 60).points
    from engine.skeleton import FEET, JOINT_INDEX
    l, r = JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"]
    stands = before[list(FEET), 0].mean()                      # about where it stands: its feet
    assert after[l][1] == pytest.approx(before[r][1])
    assert after[l][0] == pytest.approx(2 * stands - before[r][0])
    assert after[list(FEET), 0].mean() == pytest.approx(stands)


def test_signals_fire_only_on_change(doc):
    seen = []
    doc.frameChanged.connect(seen.append)
    doc.set_frame(5)
    doc.set_frame(5)
    doc.set_frame(10_000)
    assert seen == [5, 119]


def test_save_and_reload_is_byte_identical(doc, tmp_path):
    path = tmp_path / "sb.json"
    doc.storyboard.save(path)
    again = tmp_path / "again.json"
    Storyboard.load(path).save(again)
    assert path.read_bytes() == again.read_bytes()


def test_stroke_is_smoothed_and_evenly_resampled():
    raw = np.stack([np.linspace(0, 1, 200), 0.01 * np.random.default_rng(0).normal(size=200)], -1)
    out = clean_stroke(raw)
    steps = np.linalg.norm(np.diff(out, axis=0), axis=-1)
    assert np.allclose(steps, steps.mean(), rtol=0.15)  # chords of an even arc-length split
    assert np.abs(out[1:-1, 1]).max() < np.abs(raw[:, 1]).max()


def test_a_stroke_keeps_its_shape_however_fast_it_was_drawn():
    """A 1.6 m semicircle drawn slowly (40 mouse samples) or fast (7): the same arc, not one
    flattened by averaging over fewer, further-apart samples."""
    arc = lambda n: 0.8 * np.stack([-np.cos(np.linspace(0, np.pi, n)), np.sin(np.linspace(0, np.pi, n))], -1)
    slow, fast = clean_stroke(arc(40)), clean_stroke(arc(7))
    assert slow[:, 1].max() > 0.77 and fast[:, 1].max() > 0.75


def test_a_minute_of_scribbling_is_a_stroke_a_file_can_hold():
    """Back and forth over 2 m for 400 m of pen: no more points than a storyboard may hold, so
    the file it is saved in opens again."""
    raw = np.stack([2.0 * np.abs(np.sin(np.linspace(0, 200 * np.pi, 20_000))), np.linspace(0, 1, 20_000)], -1)
    out = clean_stroke(raw)
    assert len(out) == MAX_POLYLINE_POINTS
    sb = sample_storyboard()
    sb.trajectories[0].points = out
    assert len(Storyboard.from_json(sb.to_json()).trajectories[0].points) == MAX_POLYLINE_POINTS


def test_splice_replaces_only_the_redrawn_part():
    line = clean_stroke(np.array([[0.0, 0.0], [2.0, 0.0]]))
    bump = np.array([[0.8, 0.01], [1.0, 0.3], [1.2, 0.01]])
    out = splice(line, bump, snap=0.05)
    assert out is not None and out[:, 1].max() > 0.2
    assert out[0] == pytest.approx([0, 0]) and out[-1] == pytest.approx([2, 0])
    assert splice(line, bump + 1.0, snap=0.05) is None
