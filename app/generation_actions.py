"""The main window's generation: starting, cancelling and showing a generation's progress and
result, and the CPU threads it may use, as a part of MainWindow (it reads the window's document,
session, settings, viewport, properties, progress bar and actions).
"""
from __future__ import annotations

from dataclasses import replace

from PySide6.QtGui import QAction, QActionGroup

from engine.cpu import usable_cores
from engine.sampling.events import GenerationResult, StepEvent

from .generation import GenerationSettings

THREADS_KEY = "generation/threads"   # 0 or absent: automatic
OUTDATED_NOTICE = "The sketch has changed since this motion: Ctrl+Enter generates it again."
PREVIEW_NOTICE = "A quick preview: on release (or Ctrl+Enter) it is generated in full."


class GenerationActions:
    """Mixed into MainWindow: needs self.doc, self.session, self.settings, self.viewport,
    self.properties, self.progress, self.act_generate, self.act_cancel and QMainWindow's
    statusBar() and error()."""

    def _build_threads_menu(self, menu) -> None:
        """Automatic (the cores other programs leave free, engine.cpu) or a fixed count; a
        preference of this machine, kept in the settings."""
        menu.setToolTipsVisible(True)
        group = QActionGroup(self)
        cores = usable_cores()
        counts = [0] + sorted({n for n in (1, 2, 4, 8, 16, 32, 64) if n < cores} | {cores})
        current = self.threads_preference() or 0
        self.threads_actions: dict[int, QAction] = {}
        for n in counts:
            act = menu.addAction("Automatic" if n == 0 else f"{n} thread{'s' * (n > 1)}")
            act.setCheckable(True)
            act.setChecked(n == current)
            act.triggered.connect(lambda _=False, n=n: self.settings.setValue(THREADS_KEY, n))
            group.addAction(act)
            self.threads_actions[n] = act
        self.threads_actions[0].setToolTip("Use the cores that other programs leave free, re-measured while generating")

    def threads_preference(self) -> int | None:
        """The torch thread count chosen in Generate > CPU Threads; None for automatic."""
        try:
            n = int(self.settings.value(THREADS_KEY, 0) or 0)
        except (TypeError, ValueError):
            return None
        return n if n > 0 else None

    def generation_settings(self) -> GenerationSettings:
        """The document's settings with this machine's: threads, and under software OpenGL (which
        draws the streamed previews on the same cores) a core left to the drawing."""
        return replace(self.doc.settings, threads=self.threads_preference(),
                       reserve_cores=1.0 if self.viewport.draws_on_cpu() else 0.0)

    def generate(self, after_drag: bool = False) -> None:
        if self.session.busy:    # a preview, or a cancelled generation, gives way
            self.statusBar().showMessage("A generation is running: Esc cancels it.", 5000)
            return
        self.properties.commit_text()    # typed, not yet confirmed with Enter
        settings = replace(self.generation_settings(), after_drag=after_drag)
        problem = self.session.start(settings)
        if problem is not None:
            self.error(problem)
            return
        self.progress.setRange(0, settings.steps)
        self.progress.setValue(0)
        self.statusBar().showMessage("Generating\u2026  (Esc cancels)")

    def _cancel(self) -> None:
        """Esc: said at once (the cancel lands at the end of the step under way), and Generate
        is offered again (it waits for the cancel: pressed meanwhile it was dropped unsaid)."""
        self.session.cancel()
        if self.session.cancelling:
            self.statusBar().showMessage("Cancelling\u2026")
            self.act_generate.setEnabled(True)

    def _on_running(self, running: bool) -> None:
        self.act_generate.setEnabled(not running)
        self.act_cancel.setEnabled(running)
        self.progress.setVisible(running)

    def _show_progress(self, event: StepEvent) -> None:
        self.progress.setRange(0, event.num_steps)
        self.progress.setValue(event.step + 1)
        energies = "  ".join(f"{k} {v:.3g}" for k, v in list(event.energies.items())[:4])
        if not self.session.cancelling:
            self.statusBar().showMessage(f"Generating: step {event.step + 1} / {event.num_steps}  t={event.t:.2f}  {energies}")

    def _on_failed(self, message: str) -> None:
        self.statusBar().showMessage("Generation failed; the motion shown is what it was.", 15000)
        self.error(f"Generation failed: {message}")

    def _on_generated(self, result: GenerationResult) -> None:
        count = len(result.clips)
        if self.doc.result_is_preview:
            self.statusBar().showMessage(f"Preview in {result.wall_time_s * 1000:.0f} ms; "
                                         "the full generation follows the release.", 4000)
            return
        more = f" (and {len(result.notes) - 1} more: point here for all)" if len(result.notes) > 1 else ""
        note = f" {result.notes[0]}{more}." if result.notes else ""   # what finishing could not reach, worst first
        self.statusBar().setToolTip("\n".join(result.notes))
        frames, length = (result.clips[0].num_frames if result.clips else 0), self.doc.storyboard.length
        if result.clips and frames != length:   # the clip's length changed while it was generated
            note = f" It was made for {frames} frames; the clip has {length} now: Ctrl+Enter generates it again." + note
        self._summary = (f"Generated {count} variation{'s' * (count != 1)} in {result.wall_time_s:.1f} s "
                         f"(first step after {result.first_step_s:.2f} s).{note}")
        self.statusBar().showMessage(self._summary, 15000)

    def _drop_stale_summary(self) -> None:
        """An edit outdates the last generation's summary: its misses were the sketch's before the
        edit (an undone contact's hand went on being reported)."""
        if self.statusBar().currentMessage() == getattr(self, "_summary", None):
            self.statusBar().clearMessage()
        self.statusBar().setToolTip("")

    def _update_notice(self) -> None:
        """The 3D view's notice: a drag's preview says so (mid-drag it is of a sketch the document
        does not have yet: not outdated, but ahead); other motion says when the sketch changed."""
        self.viewport.set_notice(PREVIEW_NOTICE if self.doc.result_is_preview
                                 else OUTDATED_NOTICE if self.session.outdated else "")
