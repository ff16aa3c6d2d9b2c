"""The live preview's own process: the shipped model in a real child, its previews equal to the
same preview run here, a cancelled run's late answers never taken for the next run's, a child's
failure reported as the run's own, previews here while it is not up, and no child outliving its
app (closed, or killed)."""
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from app.examples import EXAMPLES_DIR
from app.generation import GenerationSettings, start_generation
from app.preview_process import PreviewProcess
from engine.generate import run_generation
from engine.sampling.config import SamplerError
from engine.storyboard import Storyboard

PREVIEW = GenerationSettings(preview=True, threads=1)


def wait_ready(process: PreviewProcess, timeout_s: float = 120.0) -> None:
    end = time.monotonic() + timeout_s
    while not process.ready:
        assert time.monotonic() < end, "the preview process never became ready"
        time.sleep(0.05)


@pytest.fixture(scope="module")
def previews():
    process = PreviewProcess()   # no warm-up: the first preview warms it
    wait_ready(process)
    yield process
    process.close()
    assert not process.alive


@pytest.fixture(scope="module")
def storyboard():
    return Storyboard.load(EXAMPLES_DIR / "box_handoff.json")


def test_a_preview_in_the_child_is_the_preview_run_here(previews, storyboard):
    stream = previews.generate(storyboard, PREVIEW)
    remote = run_generation(stream)
    local = run_generation(start_generation(storyboard, PREVIEW))
    assert remote.network_evals == local.network_evals == 2
    np.testing.assert_allclose(remote.clips[0].joints, local.clips[0].joints, atol=1e-4)
    np.testing.assert_allclose(remote.clips[0].obj_pose, local.clips[0].obj_pose, atol=1e-4)


def test_a_full_generation_never_goes_to_the_child(previews, storyboard, monkeypatch):
    asked = []
    monkeypatch.setattr(previews, "_stream", lambda *a: asked.append(a))
    stream = previews.generate(storyboard, GenerationSettings(steps=1, use_energy=False))
    assert asked == [] and stream.gi_code is start_generation.__code__   # this process' sampler
    stream.close()


def test_a_cancelled_run_never_answers_for_the_next(previews, storyboard):
    stream = previews.generate(storyboard, PREVIEW)
    first = next(stream)
    assert (first.step, first.num_steps) == (0, 2)
    with pytest.raises(RuntimeError, match="not decoded"):
        first.preview
    stream.close()                                   # as the worker cancels: between steps
    moved = storyboard.from_json(storyboard.to_json())
    moved.keyposes[0].points[:] += 0.05
    result = run_generation(previews.generate(moved, PREVIEW))
    expected = run_generation(start_generation(moved, PREVIEW))
    np.testing.assert_allclose(result.clips[0].joints, expected.clips[0].joints, atol=1e-4)


def test_a_failure_in_the_child_is_the_runs_own(previews, storyboard):
    with pytest.raises(SamplerError, match="variations must be at least 1"):
        run_generation(previews.generate(storyboard, GenerationSettings(preview=True, variations=0)))
    assert previews.ready   # and it serves the next
    assert run_generation(previews.generate(storyboard, PREVIEW)).clips


def test_previews_run_here_while_the_child_is_gone(storyboard):
    process = PreviewProcess()
    wait_ready(process)
    stream = process.generate(storyboard, PREVIEW)
    next(stream)
    process._process.kill()
    with pytest.raises(RuntimeError, match="the preview process stopped"):
        run_generation(stream)
    process._process.wait(10)
    assert not process.ready
    assert process.generate(storyboard, PREVIEW).gi_code is start_generation.__code__   # here, as before it was up
    process.close()


def test_a_killed_app_leaves_no_preview_process(tmp_path):
    script = textwrap.dedent("""
        import os, sys, time
        from app.preview_process import PreviewProcess
        if __name__ == "__main__":
            process = PreviewProcess()
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
        assert time.monotonic() < end, "the preview process outlived its killed app"
        time.sleep(0.1)


def _alive(pid: int) -> bool:
    """A process that exists and is not a zombie waiting for its (gone) parent to reap it."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_a_drag_in_the_window_is_previewed_in_the_child(qtbot, make_window, previews, monkeypatch):
    from PySide6.QtCore import Qt

    from app import commands as cmd

    from .fakes import sample_storyboard
    from .test_live_preview import WRIST, drag_wrist, px

    streamed = []
    stream = previews._stream
    monkeypatch.setattr(previews, "_stream", lambda sb, settings: (streamed.append(sb), stream(sb, settings))[1])
    window = make_window(generate=previews.generate)
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.doc.set_frame(60)
    window.doc.set_tool("select")
    resting = drag_wrist(qtbot, window, [np.array([0.004 * i, 0.002 * i]) for i in range(1, 21)])
    qtbot.waitUntil(lambda: window.doc.result_is_preview and not window.session.running, timeout=20000)
    assert streamed                                          # the previews ran in the child
    dragged = cmd.find_keypose(streamed[-1], "A", 60).points[WRIST]
    np.testing.assert_allclose(dragged, resting, atol=0.01)  # the newest of them: the resting pointer's
    assert window.doc.clip is not None and np.isfinite(window.doc.clip.joints).all()
    previewed = len(streamed)
    qtbot.mouseRelease(window.canvas, Qt.LeftButton, pos=px(window.canvas, resting))
    qtbot.waitUntil(lambda: bool(window.doc.takes) and not window.session.running, timeout=60000)
    assert len(streamed) == previewed and not window.doc.result_is_preview   # the full generation ran here
