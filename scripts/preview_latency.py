"""How long the app's live preview takes to show after the pointer stops (issue 20: 150 ms).

Opens a bundled example in the real window with the shipped model (warmed up as app.main does),
then, again and again, presses on a person's wrist at a key, drags it with a mouse move every
16 ms for 0.8 s, rests with the button down and measures the time from the last move to the 3D
view's picture of the preview of the resting storyboard. Prints each drag and the median / worst.

    xvfb-run -a -s "-screen 0 1366x768x24" .venv/bin/python scripts/preview_latency.py [EXAMPLE FRAME DRAGS]
"""
from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("LP_NUM_THREADS", "0")   # as app.main sets it
from PySide6.QtCore import QEventLoop, QPoint, QPointF, QSettings, Qt, QTimer  # noqa: E402
from PySide6.QtGui import QMouseEvent  # noqa: E402
from PySide6.QtWidgets import QApplication  # noqa: E402

from app import commands as cmd  # noqa: E402
from app.engine_process import EngineProcess  # noqa: E402
from app.examples import EXAMPLES_DIR  # noqa: E402
from app.mainwindow import MainWindow  # noqa: E402
from engine.skeleton import JOINT_INDEX  # noqa: E402

WRIST = JOINT_INDEX["r_wrist"]


def rest(ms: int) -> None:
    """Run the event loop (and let the generation thread run) for ms."""
    loop = QEventLoop()
    QTimer.singleShot(ms, loop.quit)
    loop.exec()


def main(example: str = "box_handoff", frame: int = 49, drags: int = 8) -> None:
    engine = EngineProcess(EXAMPLES_DIR / "box_handoff.json")   # as app.main starts it
    app = QApplication(sys.argv[:1])
    folder = Path(tempfile.mkdtemp(prefix="preview_latency_"))
    window = MainWindow(data_dir=folder / "data", settings=QSettings(str(folder / "settings.ini"), QSettings.IniFormat),
                        generate=engine.generate)
    window.resize(1366, 740)
    window.show()
    window.open_file(str(EXAMPLES_DIR / f"{example}.json"))
    rendered: list[float] = []          # when the 3D view finished a picture
    ended: list[tuple[float, float]] = []   # (when, the preview's own seconds) per finished run
    render = window.viewport._render
    window.viewport._render = lambda: (render(), rendered.append(time.perf_counter()))
    window.session.finished.connect(lambda result: ended.append((time.perf_counter(), result.wall_time_s)))
    while not engine.ready:             # its warm-up (and the view's)
        rest(500)
    rest(2000)
    window.doc.set_frame(frame)
    window.doc.set_tool("select")
    canvas = window.canvas

    def at(uv) -> QPoint:
        x, y = canvas.to_px(uv)
        return QPoint(round(x), round(y))

    def send(kind, pos: QPoint, button, buttons) -> None:
        QApplication.sendEvent(canvas, QMouseEvent(kind, QPointF(pos), QPointF(canvas.mapToGlobal(pos)),
                                                   button, buttons, Qt.NoModifier))

    shown_after, own = [], []
    for drag in range(drags):
        start = cmd.find_keypose(window.doc.storyboard, "A", frame).points[WRIST].copy()
        direction = np.array([np.cos(1.1 * drag), np.sin(1.1 * drag)])
        send(QMouseEvent.MouseButtonPress, at(start), Qt.LeftButton, Qt.LeftButton)
        for i in range(1, 50):
            pos = at(start + 0.006 * i * direction)
            send(QMouseEvent.MouseMove, pos, Qt.NoButton, Qt.LeftButton)
            rest(16)
        stopped = time.perf_counter()
        rest(1200)
        last_end, seconds = max(ended)
        shown = min(t for t in rendered if t >= last_end)
        shown_after.append(1000 * (shown - stopped))
        own.append(1000 * seconds)
        print(f"drag {drag}: shown {shown_after[-1]:.0f} ms after the pointer stopped "
              f"(the last preview ran {own[-1]:.0f} ms)", flush=True)
        send(QMouseEvent.MouseButtonRelease, pos, Qt.LeftButton, Qt.NoButton)
        rest(2000)                      # the release's full generation
        window.doc.undo_stack.undo()
        rest(300)
    print(f"{example}, {drags} drags: shown after the stop median {statistics.median(shown_after):.0f} ms, "
          f"worst {max(shown_after):.0f} ms; the last preview's own time median {statistics.median(own):.0f} ms")
    sys.stdout.flush()
    os._exit(0)   # closing the window would ask to save its takes


if __name__ == "__main__":
    main(*[int(a) if a.isdigit() else a for a in sys.argv[1:]])
