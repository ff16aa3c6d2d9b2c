"""`sketch2colab-studio`: start the desktop app (optionally opening a storyboard file)."""
from __future__ import annotations

import os
import sys
from pathlib import Path

NO_DISPLAY = ("sketch2colab-studio needs a display, and none was found (DISPLAY and WAYLAND_DISPLAY "
              "are unset). On a machine without a screen, run `sketch2colab demo` instead, or set "
              "QT_QPA_PLATFORM=offscreen.")


def has_display() -> bool:
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                or os.environ.get("QT_QPA_PLATFORM", "").startswith(("offscreen", "minimal", "vnc")))


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not has_display():
        print(NO_DISPLAY, file=sys.stderr)
        return 2
    # Software OpenGL (Mesa's llvmpipe) draws on the GUI thread, within the core a generation
    # leaves the view (reserve_cores): with a thread of its own per core, it took both cores from
    # the live preview (2 cores under Xvfb: 195-222 ms median from the pointer's stop to the
    # preview shown, against 165-188 ms). A hardware driver ignores the variable.
    os.environ.setdefault("LP_NUM_THREADS", "0")
    from PySide6.QtCore import QSettings, QStandardPaths
    from PySide6.QtWidgets import QApplication

    from .engine_process import EngineProcess
    from .examples import EXAMPLES_DIR
    from .mainwindow import APP_NAME, MainWindow

    engine = EngineProcess(EXAMPLES_DIR / "box_handoff.json")   # first: the model loads while the window opens
    app = QApplication([sys.argv[0], *argv])
    app.setOrganizationName("Sketch2Colab")
    app.setApplicationName(APP_NAME)
    data_dir = Path(QStandardPaths.writableLocation(QStandardPaths.AppDataLocation))
    window = MainWindow(data_dir=data_dir, settings=QSettings(), generate=engine.generate)
    window.show()
    recovered = window.offer_recovery()
    files = [a for a in argv if not a.startswith("-")]
    if files and not recovered:
        window.open_file(files[0])
    try:
        return app.exec()
    finally:
        engine.close()


if __name__ == "__main__":
    sys.exit(main())
