"""Autosave and crash recovery, per running window.

Each window keeps its unsaved work in a session folder of its own, `sessions/<pid>-<ms>/` under
the data folder, held by a lock file while the window lives: a second window never mistakes a
live window's work for a crash's, nor deletes it. Every edit, and every new take, schedules a
save a moment later (`delay_ms`: a burst of edits writes once); the storyboard is turned into
JSON on the GUI thread (a snapshot, cheap) and written on a background thread, atomically, with
the document's takes beside it (those of the file it was opened from too, and any motion shown
that is not a take). A kill at any moment loses at most the last second. A clean save
clears the session; a deliberate close removes it. At start, a session folder whose lock nobody
holds is a crash's, and the app offers to reopen it; one that cannot be read is set aside
(renamed), reported, never raised.
"""
from __future__ import annotations

import os
import shutil
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from PySide6.QtCore import QLockFile, QObject, QTimer

from engine.atomic import write_text
from engine.clip import MotionClip
from engine.storyboard import Storyboard
from engine.takes import Take, load_takes, save_takes

from .document import Document

SESSIONS = "sessions"
LOCK = "lock"
RECOVERY_FILE = "recovery.storyboard.json"
SOURCE_NOTE = "recovery.source.txt"
TAKE_FILE = "recovery.take.npz"       # the motion shown when it is no take (a preview, a recovery)
TAKES_FILE = "recovery.takes.npz"     # every take (engine.takes)


@dataclass
class Recovery:
    folder: Path
    source: Path | None      # the file the unsaved work belongs to, None for an untitled document

    def load(self) -> tuple[Storyboard, list[Take], MotionClip | None]:
        """The storyboard, its takes and the motion shown if it was no take (StoryboardError,
        TakesError, ClipError, OSError when damaged)."""
        storyboard = Storyboard.load(self.folder / RECOVERY_FILE)
        takes, shown = self.folder / TAKES_FILE, self.folder / TAKE_FILE
        return (storyboard, load_takes(takes) if takes.exists() else [],
                MotionClip.load(shown) if shown.exists() else None)

    def discard(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)

    def set_aside(self) -> Path:
        """Keep a damaged recovery out of the way (for a person to look at), under a new name."""
        target = self.folder.with_name(self.folder.name + ".unreadable")
        self.folder.rename(target)
        return target


def find_recoveries(directory: Path) -> list[Recovery]:
    """Sessions left behind by windows that are gone (their lock is free), newest first."""
    found = []
    for folder in sorted((Path(directory) / SESSIONS).glob("*"), key=lambda p: p.stat().st_mtime, reverse=True):
        if not folder.is_dir() or folder.suffix == ".unreadable":
            continue
        lock = QLockFile(str(folder / LOCK))
        if not lock.tryLock(0):               # a live window holds it
            continue
        lock.unlock()
        if not (folder / RECOVERY_FILE).exists():
            if time.time() - folder.stat().st_mtime > 10:   # not one a starting window is locking now
                shutil.rmtree(folder, ignore_errors=True)   # closed or crashed with nothing unsaved
            continue
        try:
            source = (folder / SOURCE_NOTE).read_text(encoding="utf-8").strip()
        except (OSError, UnicodeDecodeError):
            source = ""
        found.append(Recovery(folder, Path(source) if source else None))
    return found


class Autosaver(QObject):
    def __init__(self, document: Document, directory: Path, delay_ms: int = 400, parent: QObject | None = None):
        super().__init__(parent)
        self._doc = document
        self.directory = Path(directory)
        self.session = self.directory / SESSIONS / f"{os.getpid()}-{int(time.time() * 1000)}"
        self._lock: QLockFile | None = None
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(delay_ms)
        self._timer.timeout.connect(self.save_now)
        self._pending: tuple | None = None        # the newest snapshot the writer has not written
        self._written_take: MotionClip | None = None
        self._written_takes: tuple = ()            # (id, chosen) of each take written
        self._wake = threading.Condition()
        self._stopping = False
        self._writer = threading.Thread(target=self._write_loop, name="autosave", daemon=True)
        self._writer.start()
        for signal in (document.storyboardChanged, document.resultChanged, document.pathChanged):
            signal.connect(self._timer.start)
        document.dirtyChanged.connect(lambda dirty: self._timer.start() if dirty else self.clear())

    # ---- GUI thread ------------------------------------------------------------------------
    def save_now(self) -> None:
        """Snapshot the unsaved work and hand it to the writer (nothing when there is none)."""
        doc = self._doc
        if not doc.dirty:
            return
        shown = doc.takes[doc.take_index].clip if 0 <= doc.take_index < len(doc.takes) else None
        with self._wake:
            self._pending = (doc.storyboard.to_json(), str(doc.path or ""), None if doc.clip is shown else doc.clip,
                             list(doc.takes))
            self._wake.notify()

    def flush(self, timeout_s: float = 10.0) -> None:
        """Wait until the writer has written every snapshot handed to it."""
        deadline = time.monotonic() + timeout_s
        with self._wake:
            while self._pending is not None and time.monotonic() < deadline:
                self._wake.wait(0.05)

    def clear(self) -> None:
        """The work is saved: the session holds nothing to recover."""
        self._timer.stop()
        with self._wake:
            self._pending = None
            self._written_take, self._written_takes = None, ()
            for name in (RECOVERY_FILE, SOURCE_NOTE, TAKE_FILE, TAKES_FILE):
                (self.session / name).unlink(missing_ok=True)

    def stop(self) -> None:
        """A deliberate close: stop writing and remove the session."""
        self._timer.stop()
        with self._wake:
            self._stopping = True
            self._pending = None
            self._wake.notify()
        self._writer.join(5.0)
        if self._lock is not None:
            self._lock.unlock()
        shutil.rmtree(self.session, ignore_errors=True)

    # ---- writer thread ---------------------------------------------------------------------
    def _write_loop(self) -> None:
        while True:
            with self._wake:
                while self._pending is None and not self._stopping:
                    self._wake.wait()
                if self._stopping:
                    return
                try:
                    self._write(*self._pending)
                except OSError as e:
                    print(f"autosave skipped: {e}")
                self._pending = None
                self._wake.notify_all()

    def _write(self, text: str, source: str, take: MotionClip | None, takes: list[Take]) -> None:
        """Under the lock of the condition: `clear` never races a half-finished round."""
        if self._lock is None:
            self.session.mkdir(parents=True, exist_ok=True)
            self._lock = QLockFile(str(self.session / LOCK))
            self._lock.setStaleLockTime(0)          # stale only when its process is gone
            self._lock.tryLock(0)
        if take is not self._written_take:          # motion is large: written when it changes
            if take is None:
                (self.session / TAKE_FILE).unlink(missing_ok=True)
            else:
                take.save(self.session / TAKE_FILE)
            self._written_take = take
        signature = tuple((id(t), t.chosen) for t in takes)
        if signature != self._written_takes:
            if takes:
                save_takes(takes, self.session / TAKES_FILE)
            else:
                (self.session / TAKES_FILE).unlink(missing_ok=True)
            self._written_takes = signature
        write_text(self.session / SOURCE_NOTE, source)
        write_text(self.session / RECOVERY_FILE, text)
