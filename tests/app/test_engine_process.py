"""The generation process: the shipped model in a real child, its previews and full generations
equal to the same runs here (the steps to show decoded there, the rest not), a cancelled run's late
answers never taken for the next run's, a child's failure reported as the run's own, a stopped
child started again by the next run, and no child outliving its app (closed, or killed)."""
import os
import subprocess
import sys
import textwrap
import threading
import time
from multiprocessing import Pipe
from pathlib import Path

import numpy as np
import pytest

from app.examples import EXAMPLES_DIR
from app.generation import GenerationSettings, start_generation
from app.engine_process import EngineProcess, _run
from engine.generate import run_generation
from engine.sampling.config import SamplerError
from engine.storyboard import Storyboard

PREVIEW = GenerationSettings(preview=True, threads=1)


def wait_ready(process: EngineProcess, timeout_s: float = 120.0) -> None:
    end = time.monotonic() + timeout_s
    while not process.ready:
        assert time.monotonic() < end, "the generation process never became ready"
        time.sleep(0.05)


@pytest.fixture(scope="module")
def engine():
    process = EngineProcess()   # no warm-up: the first run warms it
    wait_ready(process)
    yield process
    process.close()
    assert not process.alive


@pytest.fixture(scope="module")
def storyboard():
    return Storyboard.load(EXAMPLES_DIR / "box_handoff.json")


def test_a_preview_in_the_child_is_the_preview_run_here(engine, storyboard):
    stream = engine.generate(storyboard, PREVIEW)
    remote = run_generation(stream)
    local = run_generation(start_generation(storyboard, PREVIEW))
    assert remote.network_evals == local.network_evals == 2
    np.testing.assert_allclose(remote.clips[0].joints, local.clips[0].joints, atol=1e-4)
    np.testing.assert_allclose(remote.clips[0].obj_pose, local.clips[0].obj_pose, atol=1e-4)


def test_a_full_generation_streams_the_steps_to_show_decoded(engine, storyboard):
    settings = GenerationSettings(steps=3, use_energy=False, threads=1)
    stream, events = engine.generate(storyboard, settings), []
    try:
        while True:
            events.append(next(stream))
    except StopIteration as stop:
        remote = stop.value
    local = run_generation(start_generation(storyboard, settings))
    assert [e.step for e in events] == [0, 1, 2]
    assert events[0].decode is not None and events[-1].decode is not None   # the first and the last are shown
    assert events[-1].preview.joints.shape == local.clips[0].joints.shape
    np.testing.assert_allclose(remote.clips[0].joints, local.clips[0].joints, atol=1e-4)


def test_a_cancelled_run_never_answers_for_the_next(engine, storyboard):
    stream = engine.generate(storyboard, PREVIEW)
    first = next(stream)
    assert (first.step, first.num_steps) == (0, 2)
    assert first.decode is None                      # a preview's steps are not shown
    stream.close()                                   # as the worker cancels: between steps
    moved = storyboard.from_json(storyboard.to_json())
    moved.keyposes[0].points[:] += 0.05
    result = run_generation(engine.generate(moved, PREVIEW))
    expected = run_generation(start_generation(moved, PREVIEW))
    np.testing.assert_allclose(result.clips[0].joints, expected.clips[0].joints, atol=1e-4)


@pytest.mark.parametrize("cancelled", [7, 6])
def test_a_cancel_while_the_run_finishes_stops_it_there_unless_it_is_an_older_runs(storyboard, cancelled):
    ours, theirs = Pipe()
    settings = GenerationSettings(steps=2, use_energy=False, variations=3, threads=1)
    child = threading.Thread(target=_run, args=(theirs, 7, storyboard, settings))
    child.start()
    while (message := ours.recv())[0] == "step" and message[2] < 1:
        pass
    assert message[:3] == ("step", 7, 1)             # the last step: the finishing follows
    time.sleep(0.05)                                 # into it (3 clips, 0.15 s each on 2 cores)
    ours.send(("cancel", cancelled))
    answer = ours.recv()
    child.join(60)
    assert answer[:2] == (("cancelled", 7) if cancelled == 7 else ("done", 7))


def test_a_cancel_from_another_thread_stops_the_run_while_its_stream_waits(engine, storyboard):
    settings = GenerationSettings(steps=2, use_energy=False, variations=3, threads=1)
    stream = engine.generate(storyboard, settings)
    assert [next(stream).step for _ in range(2)] == [0, 1]   # the child finishes 3 clips now
    threading.Timer(0.05, stream.cancel).start()
    with pytest.raises(RuntimeError, match="cancelled"):
        next(stream)
    assert run_generation(engine.generate(storyboard, PREVIEW)).clips   # and it serves the next


def test_a_failure_in_the_child_is_the_runs_own(engine, storyboard):
    with pytest.raises(SamplerError, match="variations must be at least 1"):
        run_generation(engine.generate(storyboard, GenerationSettings(preview=True, variations=0)))
    assert engine.ready   # and it serves the next
    assert run_generation(engine.generate(storyboard, PREVIEW)).clips


def test_a_stopped_child_fails_its_run_and_the_next_run_starts_another(storyboard):
    process = EngineProcess()
    wait_ready(process)
    stream = process.generate(storyboard, PREVIEW)
    next(stream)
    process._process.kill()
    with pytest.raises(RuntimeError, match="the generation process stopped"):
        run_generation(stream)
    process._process.wait(10)
    assert not process.ready
    assert run_generation(process.generate(storyboard, PREVIEW)).clips   # waits for a new child
    assert process.alive
    process.close()


def test_a_killed_app_leaves_no_generation_process(tmp_path):
    script = textwrap.dedent("""
        import os, sys, time
        from app.engine_process import EngineProcess, _run
        if __name__ == "__main__":
            process = EngineProcess()
            print(process._process.pid, flush=True)
            while not process.ready:
                time.sleep(0.05)
            print("ready", flush=True)
            time.sleep(600)
    """)
    (tmp_path / "app_like.py").write_text(script)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[2])}
    app_like = subprocess.Popen([sys.executable, str(tmp_path / "app_like.py")], stdout=subprocess.PIPE, text=True, env=env)
    child = int(app_like.stdout.readline())
    assert app_like.stdout.readline().strip() == "ready"
    app_like.kill()
    app_like.wait()
    end = time.monotonic() + 30
    while _alive(child):
        assert time.monotonic() < end, "the generation process outlived its killed app"
        time.sleep(0.1)


def _alive(pid: int) -> bool:
    """A process that exists and is not a zombie waiting for its (gone) parent to reap it."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_a_drag_in_the_window_is_previewed_and_generated_in_the_child(qtbot, make_window, engine):
    from PySide6.QtCore import Qt

    from app import commands as cmd

    from .fakes import sample_storyboard
    from .test_live_preview import WRIST, drag_wrist, px

    asked = []                                               # (storyboard, preview) per run

    def generate(storyboard, settings):
        asked.append((storyboard, settings.preview))
        return engine.generate(storyboard, settings)

    window = make_window(generate=generate)
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.doc.set_frame(60)
    window.doc.set_tool("select")
    resting = drag_wrist(qtbot, window, [np.array([0.004 * i, 0.002 * i]) for i in range(1, 21)])
    qtbot.waitUntil(lambda: window.doc.result_is_preview and not window.session.running, timeout=20000)
    assert asked and all(preview for _, preview in asked)
    dragged = cmd.find_keypose(asked[-1][0], "A", 60).points[WRIST]
    np.testing.assert_allclose(dragged, resting, atol=0.01)  # the newest preview: the resting pointer's
    assert window.doc.clip is not None and np.isfinite(window.doc.clip.joints).all()
    shown = []
    window.session.stepped.connect(lambda event: shown.append(event.preview))
    qtbot.mouseRelease(window.canvas, Qt.LeftButton, pos=px(window.canvas, resting))
    qtbot.waitUntil(lambda: bool(window.doc.takes) and not window.session.running, timeout=60000)
    assert not asked[-1][1] and not window.doc.result_is_preview   # the release's full generation
    assert shown and all(np.isfinite(clip.joints).all() for clip in shown)   # its steps reached the views


def test_the_window_process_never_loads_the_model(tmp_path):
    script = textwrap.dedent(f"""
        import sys
        from PySide6.QtCore import QSettings
        from PySide6.QtWidgets import QApplication
        from app.examples import EXAMPLES_DIR
        from app.mainwindow import MainWindow
        app = QApplication([])
        window = MainWindow(data_dir={str(tmp_path / "data")!r},
                            settings=QSettings({str(tmp_path / "s.ini")!r}, QSettings.IniFormat))
        window.show()
        window.open_file(str(EXAMPLES_DIR / "box_handoff.json"))
        app.processEvents()
        print(sorted(m for m in sys.modules if m.split(".")[0] == "torch")[:3])
    """)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[2]), "QT_QPA_PLATFORM": "offscreen"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]"   # torch stays in the generation process
