"""GUI tests run headless, on one 1366 x 768 screen (a laptop's): the platform must be chosen
before Qt loads."""
import gc
import os
from pathlib import Path

if os.environ.get("QT_QPA_PLATFORM", "offscreen") == "offscreen":
    os.environ["QT_QPA_PLATFORM"] = f"offscreen:configfile={Path(__file__).with_name('laptop_screen.json')}"

import pytest  # noqa: E402
from PySide6.QtCore import QSettings, QThread  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from .fakes import FakeSampler  # noqa: E402


@pytest.fixture(autouse=True)
def join_threads(qapp):
    """After each test, quit and join every QThread still alive, so none outlives its test, and
    free what the test left to the garbage collector: collected at a later, random moment (inside
    an engine test after the GUI tests), a Qt object's teardown crashed the process."""
    yield
    for obj in gc.get_objects():
        if issubclass(type(obj), QThread) and obj is not qapp.thread():  # type(): no proxies poked
            try:
                obj.quit()
                assert obj.wait(5000), "a QThread did not finish"
            except RuntimeError:  # its C++ side is already gone
                pass
    gc.collect()


class DialogRecorder:
    """Stands in for QMessageBox's static dialogs: records messages, answers questions."""

    def __init__(self):
        self.errors: list[str] = []
        self.questions: list[str] = []
        self.answer = QMessageBox.Discard

    def critical(self, parent, title, text, *args, **kwargs):
        self.errors.append(text)
        return QMessageBox.Ok

    def question(self, parent, title, text, *args, **kwargs):
        self.questions.append(text)
        return self.answer


@pytest.fixture
def dialogs(monkeypatch):
    recorder = DialogRecorder()
    monkeypatch.setattr(QMessageBox, "critical", recorder.critical)
    monkeypatch.setattr(QMessageBox, "question", recorder.question)
    return recorder


@pytest.fixture
def make_window(qtbot, tmp_path, dialogs):
    """Build main windows with a private data folder and settings file and a fake sampler."""
    from app.mainwindow import MainWindow
    windows = []

    def make(generate=None, autosave_delay_ms=400):
        settings = QSettings(str(tmp_path / "settings.ini"), QSettings.IniFormat)
        window = MainWindow(data_dir=tmp_path / "data", settings=settings, generate=generate or FakeSampler(),
                            autosave_delay_ms=autosave_delay_ms)
        qtbot.addWidget(window)
        window.show()
        windows.append(window)
        return window

    yield make
    for window in windows:
        window.shutdown()


@pytest.fixture
def window(make_window):
    return make_window()
