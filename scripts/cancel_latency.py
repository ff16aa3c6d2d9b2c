"""How soon a preview follows a full generation cancelled as it finishes (a drag begun just after
a release): from the last step of a full generation in the generation process (app.engine_process)
to the end of the preview asked for next, the full run cancelled at that moment.

    .venv/bin/python scripts/cancel_latency.py [EXAMPLE RUNS]
"""
from __future__ import annotations

import statistics
import sys
import time

from app.engine_process import EngineProcess
from app.examples import EXAMPLES_DIR
from app.generation import GenerationSettings
from engine.generate import run_generation
from engine.storyboard import Storyboard


def main(example: str = "box_handoff", runs: int = 12) -> None:
    path = EXAMPLES_DIR / f"{example}.json"
    storyboard, engine, took = Storyboard.load(path), EngineProcess(path), []
    while not engine.ready:
        time.sleep(0.05)
    for _ in range(runs):
        stream = engine.generate(storyboard, GenerationSettings())
        while (event := next(stream)).step < event.num_steps - 1:
            pass
        start = time.perf_counter()
        stream.cancel()                    # as the worker does when the drag's first preview is asked for
        try:
            next(stream)
        except (StopIteration, RuntimeError):
            pass
        run_generation(engine.generate(storyboard, GenerationSettings(preview=True)))
        took.append(1000 * (time.perf_counter() - start))
    engine.close()
    print(f"{example}, {runs} runs: last step of a full generation -> the next preview done, median "
          f"{statistics.median(took):.0f} ms, worst {max(took):.0f} ms")


if __name__ == "__main__":
    main(*(sys.argv[1:2] or ["box_handoff"]), *(int(a) for a in sys.argv[2:3]))
