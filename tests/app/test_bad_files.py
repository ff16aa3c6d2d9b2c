"""Bad files from every way in (Open, the command line) end in a one-line dialog or a document
the widgets can draw, never in an exception out of an event handler."""
import copy
import json
import random

from tests.engine.test_storyboard_fuzz import EXAMPLES, _leaves, _set

JUNK = [None, True, -1, 10 ** 400, 1e300, float("nan"), "x", [], {}, 5.0, 200.0, [[0.1, 0.2]] * 30, [3, 4]]


def mutated_files(tmp_path, count: int = 40) -> list:
    rng = random.Random(0)
    files = []
    for n in range(count):
        doc = copy.deepcopy(EXAMPLES[n % len(EXAMPLES)])
        for _ in range(rng.randint(1, 3)):
            leaves = list(_leaves(doc))
            doc = _set(doc, rng.choice(leaves), copy.deepcopy(rng.choice(JUNK)))
        path = tmp_path / f"bad{n}.json"
        try:
            path.write_text(json.dumps(doc))
        except ValueError:
            path.write_text("{ truncated")
        files.append(path)
    files.append(tmp_path / "missing.json")
    (tmp_path / "binary.json").write_bytes(bytes(range(256)))
    files.append(tmp_path / "binary.json")
    return files


def test_open_never_raises_and_what_opens_can_be_drawn(qtbot, window, tmp_path, dialogs):
    opened = 0
    for path in mutated_files(tmp_path):
        before = len(dialogs.errors)
        if window.open_file(path):
            opened += 1
            window.canvas.grab()                     # paints every keypose, path and object
            window.timeline.grab()
            window.doc.undo_stack.clear()
            window.doc.mark_saved(path)
        else:
            assert len(dialogs.errors) == before + 1 and "\n" not in dialogs.errors[-1]
    assert 0 < opened < 40


def test_a_bad_file_on_the_command_line_is_a_dialog_not_a_crash(tmp_path):
    """The real app, started with a bad file: it is still running (its one-line dialog up) after
    some seconds, with no traceback."""
    import os
    import subprocess
    import sys
    import time
    doc = copy.deepcopy(EXAMPLES[0])
    doc["keyposes"][0]["frame"] = float(doc["keyposes"][0]["frame"])   # validated, then broke the canvas
    doc["contacts"][0]["start"] = 3.0
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "HOME": str(tmp_path), "XDG_DATA_HOME": str(tmp_path),
           "XDG_CONFIG_HOME": str(tmp_path), "PYTHONPATH": os.getcwd()}
    app = subprocess.Popen([sys.executable, "-m", "app.main", str(tmp_path / "bad.json")], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(8)
    alive = app.poll() is None
    app.kill()
    _, err = app.communicate()
    assert alive and "Traceback" not in err, err[-2000:]


def drop(qtbot, window, paths):
    from PySide6.QtCore import QMimeData, QPointF, Qt, QUrl
    from PySide6.QtGui import QDropEvent
    data = QMimeData()
    data.setUrls([QUrl.fromLocalFile(str(p)) for p in paths])
    event = QDropEvent(QPointF(window.width() / 2, window.height() / 2), Qt.CopyAction, data, Qt.LeftButton,
                       Qt.NoModifier)
    window.dropEvent(event)                       # the handler a real drop reaches (Qt routes a drop only
                                                  # while a drag is in progress, which offscreen has not)


def test_dropped_files_open_or_say_why(qtbot, window, tmp_path, dialogs):
    files = mutated_files(tmp_path, count=8)
    for path in files:
        before = len(dialogs.errors)
        drop(qtbot, window, [path])
        assert len(dialogs.errors) in (before, before + 1)
        window.doc.undo_stack.clear()
        window.doc.mark_saved(path)
    (tmp_path / "bad.bvh").write_text("HIERARCHY\nROOT nothing")
    drop(qtbot, window, [tmp_path / "bad.bvh"])
    assert "bad.bvh" in dialogs.errors[-1] and "\n" not in dialogs.errors[-1]
    drop(qtbot, window, files[:3])
    assert "Drop one storyboard" in dialogs.errors[-1]
    good = tmp_path / "good.json"
    good.write_text(json.dumps(EXAMPLES[0]))
    drop(qtbot, window, [good])
    assert window.doc.path == good
