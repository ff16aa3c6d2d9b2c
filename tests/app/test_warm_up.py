"""The background warm-up (app.main starts it beside the window): it loads the model once even
when the first Generate asks for it at the same moment, runs a short real generation, and never
raises, whatever the model or the file."""
import threading
import time
from functools import lru_cache

import app.generation
from app.examples import EXAMPLES_DIR
from app.generation import GenerationSettings, warm_up
from engine.models.bundle import untrained_bundle


def test_the_model_loads_once_when_warm_up_and_generate_ask_together(monkeypatch):
    loads = []

    @lru_cache(maxsize=1)
    def slow_load():
        loads.append(threading.current_thread().name)
        time.sleep(0.3)
        return object()

    monkeypatch.setattr(app.generation, "_load_bundle", slow_load)
    got = []
    threads = [threading.Thread(target=lambda: got.append(app.generation._bundle()), name=name)
               for name in ("warm-up", "generation")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(loads) == 1 and len(got) == 2 and got[0] is got[1]


def test_warm_up_runs_a_generation_and_never_raises(monkeypatch, capsys):
    bundle = untrained_bundle()
    monkeypatch.setattr(app.generation, "_bundle", lambda: bundle)
    ran = []
    original = app.generation.start_generation
    monkeypatch.setattr(app.generation, "start_generation",
                        lambda sb, settings: (ran.append((sb.length, settings.steps)), original(sb, settings))[1])
    warm_up(EXAMPLES_DIR / "box_handoff.json", GenerationSettings(steps=1))
    assert ran == [(120, 1)] and capsys.readouterr().err == ""

    warm_up(EXAMPLES_DIR / "no_such_storyboard.json")
    assert "warm-up skipped" in capsys.readouterr().err

    monkeypatch.setattr(app.generation, "_bundle", lambda: (_ for _ in ()).throw(RuntimeError("bad checkpoint")))
    warm_up(EXAMPLES_DIR / "box_handoff.json")
    assert "bad checkpoint" in capsys.readouterr().err
