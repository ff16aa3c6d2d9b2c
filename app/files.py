"""The main window's files: open, save, recent files, exports, reference motion, drag and drop,
and crash recovery, as a part of MainWindow (it reads the window's document, settings,
viewport and autosaver).

Every failure a person can cause (a bad file, a full disk) becomes a dialog with a one-line
message, and the document stays as it was.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QMessageBox

from engine.clip import ClipError, MotionClip
from engine.export import export_gltf, export_npz, export_object_path
from engine.storyboard import Storyboard, StoryboardError
from engine.takes import TakesError, load_takes, save_takes, takes_path

from .autosave import find_recoveries
from .document import new_storyboard

APP_NAME = "Sketch2Colab Studio"
FILE_FILTER = "Storyboards (*.json);;All files (*)"
MAX_RECENT = 8
NO_MOTION = "There is no generated motion to export yet: generate first (Ctrl+Enter)."


class FileActions:
    """Mixed into MainWindow: needs self.doc, self.settings, self.viewport, self.autosaver,
    self.recent_menu and QMainWindow's statusBar()."""

    _unread_takes: Path | None = None   # the opened storyboard's takes file that could not be read

    # ---- files ----------------------------------------------------------------------------------
    def error(self, message: str) -> None:
        QMessageBox.critical(self, APP_NAME, message)

    def maybe_save(self) -> bool:
        """Ask about unsaved changes; False when the person cancels."""
        if not self.doc.dirty:
            return True
        answer = QMessageBox.question(self, APP_NAME, "Save changes to the storyboard?",
                                      QMessageBox.Save | QMessageBox.Discard | QMessageBox.Cancel,
                                      QMessageBox.Save)
        if answer == QMessageBox.Save:
            return self.save()
        return answer == QMessageBox.Discard

    def new_document(self) -> None:
        if self.maybe_save():
            self.doc.replace_storyboard(new_storyboard(), None)
            self._unread_takes = None

    def open_file(self, path: str | Path | None = None) -> bool:
        if not self.maybe_save():
            return False
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self, "Open Storyboard", self._last_dir(), FILE_FILTER)
            if not path:
                return False
        storyboard = self._load_storyboard(path, Path(path).name)
        if storyboard is None:
            if not Path(path).exists():   # a recent file deleted or moved since: off the list
                self.settings.setValue("recentFiles", [f for f in self.recent_files() if Path(f) != Path(path).resolve()])
                self._rebuild_recent()
            return False
        self.doc.replace_storyboard(storyboard, Path(path))
        self._remember(Path(path))
        takes = takes_path(path)
        self._unread_takes = None
        if takes.exists():
            try:
                self.doc.set_takes(load_takes(takes))
            except TakesError as e:
                self._unread_takes = takes.resolve()
                self.error(f"Opened {Path(path).name} without its takes: {e}")
                return True
        count = len(self.doc.takes)
        self.statusBar().showMessage(f"Opened {path}" + (f" with {count} take{'s' * (count > 1)}" if count else ""), 5000)
        return True

    def _load_storyboard(self, path: str | Path, what: str) -> Storyboard | None:
        """The storyboard at path, or None after telling the user why not (one-line dialog)."""
        try:
            return Storyboard.load(path)
        except StoryboardError as e:
            self.error(f"Cannot open {what}: {e}")
            return None

    def open_example(self, path: Path) -> bool:
        """Open a shipped example as a new, untitled storyboard: Save then asks where, so the
        example itself is never overwritten."""
        if not self.maybe_save():
            return False
        storyboard = self._load_storyboard(path, f"the example {Path(path).name}")
        if storyboard is None:
            return False
        self.doc.replace_storyboard(storyboard, None)
        self._unread_takes = None
        self.statusBar().showMessage(f"Opened the example \u201c{storyboard.text or Path(path).stem}\u201d; "
                                     "Ctrl+Enter generates.", 8000)
        return True

    def save(self) -> bool:
        return self.save_to(self.doc.path) if self.doc.path else self.save_as()

    def save_as(self) -> bool:
        path, _ = QFileDialog.getSaveFileName(self, "Save Storyboard", self._last_dir(), FILE_FILTER)
        if not path:
            return False
        path = Path(path)   # without .json the Open dialog's filter would hide the file
        return self.save_to(path if path.suffix.lower() == ".json" else path.with_name(path.name + ".json"))

    def save_to(self, path: Path) -> bool:
        path = Path(path)
        try:
            self.doc.storyboard.validate()
            self.doc.storyboard.save(path)
            self._save_takes(path)
        except (StoryboardError, OSError) as e:
            self.error(f"Cannot save {path.name}: {e}")
            return False
        self.doc.mark_saved(path)
        self._remember(path)
        self.statusBar().showMessage(f"Saved {path}", 5000)
        return True

    def _save_takes(self, path: Path) -> None:
        """The document's takes beside the storyboard at path. Without takes, a takes file there
        is another storyboard's (saved over) and goes, unless it is the one this storyboard was
        opened with and could not read (the person was told; it is left for them)."""
        target = takes_path(path)
        if self.doc.takes:
            save_takes(self.doc.takes, target)
        elif target.exists() and target.resolve() != self._unread_takes:
            target.unlink()

    def _last_dir(self) -> str:
        recent = self.recent_files()
        return str(Path(recent[0]).parent) if recent else str(Path.home())

    def recent_files(self) -> list[str]:
        value = self.settings.value("recentFiles", [])
        return [value] if isinstance(value, str) else list(value or [])

    def _remember(self, path: Path) -> None:
        files = [str(path.resolve())] + [f for f in self.recent_files() if f != str(path.resolve())]
        self.settings.setValue("recentFiles", files[:MAX_RECENT])
        self._rebuild_recent()

    def _rebuild_recent(self) -> None:
        self.recent_menu.clear()
        for f in self.recent_files():
            self.recent_menu.addAction(Path(f).name, lambda f=f: self.open_file(f)).setToolTip(f)
        self.recent_menu.setEnabled(bool(self.recent_files()))

    def _export_motion(self, title: str, file_filter: str, suffix: str,
                       write: Callable[[MotionClip, Path], Path | list[Path]]) -> bool:
        """Ask for a file and write the generated motion there with `write(clip, path)`, which
        returns the file or files it wrote."""
        clip = self.doc.clip
        if clip is None:
            self.error(NO_MOTION)
            return False
        chosen, _ = QFileDialog.getSaveFileName(self, title, self._last_dir(), file_filter)
        if not chosen:
            return False
        path = Path(chosen) if Path(chosen).suffix else Path(chosen).with_suffix(suffix)
        try:
            written = write(clip, path)
        except Exception as e:  # any exporter failure (disk, a clip it cannot take) is a dialog
            self.error(f"Cannot export {path.name}: {str(e).splitlines()[0] if str(e) else type(e).__name__}")
            return False
        names = ", ".join(p.name for p in (written if isinstance(written, list) else [written]))
        self.statusBar().showMessage(f"Exported {names} to {path.parent}", 8000)
        return True

    def export_npz(self) -> bool:
        return self._export_motion("Export Motion", "Motion clips (*.npz)", ".npz", export_npz)

    def export_bvh(self) -> bool:
        return self._export_motion("Export Motion as BVH (one file per person)", "BVH (*.bvh)", ".bvh",
                                   self._write_bvh_per_person)

    def export_gltf(self) -> bool:
        return self._export_motion("Export Scene as glTF", "glTF binary (*.glb)", ".glb", export_gltf)

    def export_object_path(self) -> bool:
        return self._export_motion("Export Object Path", "CSV (*.csv)", ".csv", export_object_path)

    def _write_bvh_per_person(self, clip: MotionClip, path: Path) -> list[Path]:
        """`<stem>_<agent id>.bvh` per person, named after the storyboard's agents."""
        from engine.io import write_bvh
        agents = self.doc.storyboard.agents
        written = []
        for h in range(clip.num_humans):
            name = agents[h].id if h < len(agents) else str(h)
            written.append(path.with_name(f"{path.stem}_{name}.bvh"))
            write_bvh(clip, h, written[-1])
        return written

    def import_bvh(self, paths: list[str] | None = None) -> None:
        from engine.io import import_bvh
        if paths is None:
            paths, _ = QFileDialog.getOpenFileNames(self, "Import Reference Motion (one BVH per person)",
                                                    self._last_dir(), "BVH (*.bvh)")
        if not paths:
            return
        try:
            clip, _report = import_bvh(paths)
        except (OSError, ValueError) as e:
            self.error(f"Cannot import {Path(paths[0]).name}: {str(e).splitlines()[0]}")
            return
        self.doc.set_reference(clip)
        self.statusBar().showMessage(f"Reference motion: {clip.num_frames} frames, {clip.num_humans} people", 5000)

    def trace_storyboard(self) -> None:
        """A new storyboard traced from the reference motion (else the generated one)."""
        from engine.sketchify import sketchify
        clip = self.doc.reference or self.doc.clip
        if clip is None:
            self.error("There is no motion to trace: import a BVH reference or generate first.")
            return
        if not self.maybe_save():
            return
        try:
            storyboard = sketchify(clip, keyframes=4, camera=self.doc.storyboard.camera)
        except ValueError as e:
            self.error(f"Cannot trace the motion: {e}")
            return
        reference = self.doc.reference
        self.doc.replace_storyboard(storyboard, None, dirty=True)
        self.doc.set_reference(reference)

    def export_png(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Export 3D View", self._last_dir(), "PNG images (*.png)")
        if path:
            path = path if Path(path).suffix else str(Path(path).with_suffix(".png"))   # as the other exports
            try:
                self.viewport.grab_png(path)
            except OSError as e:
                self.error(f"Cannot write {Path(path).name}: {e}")

    # ---- drag and drop: a storyboard opens, BVH files become the reference ---------------------
    def dragEnterEvent(self, event) -> None:
        if event.mimeData().hasUrls():
            event.acceptProposedAction()

    def dropEvent(self, event) -> None:
        paths = [u.toLocalFile() for u in event.mimeData().urls() if u.isLocalFile()]
        event.acceptProposedAction()
        bvh = [p for p in paths if p.lower().endswith(".bvh")]
        if bvh and len(bvh) == len(paths):
            self.import_bvh(bvh[:2])
        elif len(paths) == 1:
            self.open_file(paths[0])       # any other file is read as a storyboard: a bad one is a dialog
        else:
            self.error("Drop one storyboard (.json), or one or two BVH files (one per person).")

    # ---- crash recovery ------------------------------------------------------------------------
    def offer_recovery(self) -> bool:
        """At start: if a window that is gone left unsaved work behind, offer to reopen it (the
        newest; a live window's work is its own). Damaged work is set aside and reported."""
        found = find_recoveries(self.autosaver.directory)
        if not found:
            return False
        recovery = found[0]
        name = recovery.source.name if recovery.source else "an untitled storyboard"
        answer = QMessageBox.question(self, APP_NAME,
                                      f"A session ended with unsaved changes to {name}. Recover them?",
                                      QMessageBox.Yes | QMessageBox.No, QMessageBox.Yes)
        if answer != QMessageBox.Yes:
            recovery.discard()
            return False
        try:
            storyboard, takes, shown = recovery.load()
        except (StoryboardError, TakesError, ClipError, OSError) as e:
            kept = recovery.set_aside()
            self.error(f"The unsaved work could not be read ({str(e).splitlines()[0]}); it is kept in {kept}.")
            return False
        self.doc.replace_storyboard(storyboard, recovery.source, dirty=True)
        self.doc.set_takes(takes)
        if shown is not None:
            self.doc.set_result([shown], shown.phase)
        recovery.discard()
        self.autosaver.save_now()          # the recovered work is this window's now
        self.statusBar().showMessage("Recovered unsaved work; save it to keep it.", 8000)
        return True

