"""The open document: a pure model the widgets observe (napari style), no widgets here.

It holds the Storyboard, its file path, the dirty flag, the selection, the active tool and its
options, the playhead frame, the timeline's frame span, the generation settings, the takes (every
finished generation) and the clips and phase occupancy shown (a running generation is
app.session's). Storyboard
edits go through `commands.py` on `undo_stack`; every other change is a setter that emits its
signal only when the value really changes.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QUndoStack

from engine.camera import StoryboardCamera
from engine.clip import MotionClip
from engine.skeleton import JOINT_NAMES
from engine.storyboard import AGENT_COLORS, Agent, Storyboard
from engine.takes import MAX_TAKES, Take

from .generation import GenerationSettings, settings_of

TOOLS = ("select", "keypose", "trajectory", "object", "contact", "erase")
OBJECT_PATH = "object path"  # pseudo joint: the trajectory tool then draws the selected object's path


def new_storyboard() -> Storyboard:
    """The new-document default: agents A and B, 120 frames at 20 fps, the default camera."""
    return Storyboard(fps=20.0, length=120, camera=StoryboardCamera(),
                      agents=[Agent("A", "A", AGENT_COLORS[0]), Agent("B", "B", AGENT_COLORS[1])])


@dataclass(frozen=True)
class ToolOptions:
    """How the tools draw; the canvas reads them, the properties panel sets them."""
    object_shape: str = "rectangle"   # the object tool drags a "rectangle" or draws a "lasso"
    pinned: tuple[tuple[str, str], ...] = ()   # (agent, joint) pairs that stay put while that agent's
                                                # pose is dragged (engine.rig); a document's own


OBJECT_SHAPES = ("rectangle", "lasso")


@dataclass(frozen=True)
class Selection:
    agent: str | None = None
    joint: str = "pelvis"        # a JOINT_NAMES entry or OBJECT_PATH
    object: str | None = None


class Document(QObject):
    storyboardChanged = Signal()   # content edited, undone, redone or replaced
    replaced = Signal()            # a whole new storyboard (new, open, recover): views reframe
    selectionChanged = Signal()
    toolChanged = Signal(str)
    toolOptionsChanged = Signal()
    frameChanged = Signal(int)
    spanChanged = Signal()         # the timeline's frame span (used by trajectories, contacts)
    settingsChanged = Signal()
    resultChanged = Signal()       # clips, chosen variation or phase occupancy
    referenceChanged = Signal()    # imported reference motion
    pathChanged = Signal()
    dirtyChanged = Signal(bool)

    def __init__(self, storyboard: Storyboard | None = None, path: Path | None = None):
        super().__init__()
        self.undo_stack = QUndoStack(self)
        self.undo_stack.cleanChanged.connect(self._emit_dirty)
        self.storyboard = storyboard or new_storyboard()
        self.path = path
        self._unsaved_without_edits = False  # e.g. a recovered file: dirty before any edit
        self.selection = Selection(agent=self.storyboard.agents[0].id)
        self.tool = "keypose"
        self.tool_options = ToolOptions()
        self.frame = 0
        self.span: tuple[int, int] | None = None
        self.settings = GenerationSettings()
        self.clips: list[MotionClip] = []
        self.variation = 0
        self.phase: np.ndarray | None = None   # (N, 3) occupancy of the last finished generation
        self._result_source: str | None = None  # the storyboard the clips came from, as JSON
        self.result_is_preview = False         # the clips shown are a drag's quick preview, no take
        self.takes: list[Take] = []            # every generation kept (engine.takes), newest last
        self.take_index = -1                   # the take shown (-1: none, or a preview or recovery)
        self.reference: MotionClip | None = None

    # ---- whole-document changes ------------------------------------------------------------
    def replace_storyboard(self, storyboard: Storyboard, path: Path | None, dirty: bool = False) -> None:
        """New / open / recover: a fresh history, selection and result for `storyboard`."""
        self.undo_stack.clear()
        self.storyboard = storyboard
        self.path = path
        self.selection = Selection(agent=storyboard.agents[0].id,
                                   object=storyboard.objects[0].id if storyboard.objects else None)
        self.frame = 0
        self.span = None
        self.clips, self.variation, self.phase, self._result_source = [], 0, None, None
        self.result_is_preview = False
        self.takes, self.take_index = [], -1
        self._unsaved_without_edits = dirty
        self.tool_options = replace(self.tool_options, pinned=())   # pins are the old document's
        for signal in (self.storyboardChanged, self.selectionChanged, self.spanChanged,
                       self.resultChanged, self.pathChanged):
            signal.emit()
        self.frameChanged.emit(0)
        self.replaced.emit()
        self._emit_dirty()

    def mark_saved(self, path: Path) -> None:
        self.path = path
        self._unsaved_without_edits = False
        self.undo_stack.setClean()
        self.pathChanged.emit()
        self._emit_dirty()

    @property
    def dirty(self) -> bool:
        return self._unsaved_without_edits or not self.undo_stack.isClean()

    def _emit_dirty(self, *_):
        self.dirtyChanged.emit(self.dirty)

    def notify_edited(self) -> None:
        """Called by every command after it changed the storyboard."""
        self.frame = min(self.frame, self.storyboard.length - 1)
        self.storyboardChanged.emit()

    # ---- view state --------------------------------------------------------------------------
    def select(self, **changes) -> None:
        """Change selection fields, e.g. select(agent="B", joint="l_wrist")."""
        new = replace(self.selection, **changes)
        if new != self.selection:
            self.selection = new
            self.selectionChanged.emit()

    def set_tool(self, tool: str) -> None:
        if tool not in TOOLS:
            raise ValueError(f"unknown tool {tool!r}")
        if tool != self.tool:
            self.tool = tool
            self.toolChanged.emit(tool)

    def set_tool_options(self, **changes) -> None:
        """e.g. set_tool_options(object_shape="lasso")."""
        new = replace(self.tool_options, **changes)
        if new.object_shape not in OBJECT_SHAPES:
            raise ValueError(f"unknown object shape {new.object_shape!r}")
        if new != self.tool_options:
            self.tool_options = new
            self.toolOptionsChanged.emit()

    def toggle_pin(self, agent: str, joint: str) -> None:
        """Pin `agent`'s `joint` for posing, or unpin it; nothing for what is no joint (an object
        path: pinned, it stopped every drag)."""
        if joint not in JOINT_NAMES:
            return
        pin, pinned = (agent, joint), self.tool_options.pinned
        self.set_tool_options(pinned=tuple(p for p in pinned if p != pin) if pin in pinned else pinned + (pin,))

    def pinned_joints(self, agent: str) -> tuple[str, ...]:
        return tuple(joint for who, joint in self.tool_options.pinned if who == agent)

    def set_frame(self, frame: int) -> None:
        frame = int(np.clip(frame, 0, self.storyboard.length - 1))
        if frame != self.frame:
            self.frame = frame
            self.frameChanged.emit(frame)

    def set_span(self, span: tuple[int, int] | None) -> None:
        if span is not None:
            lo, hi = sorted(int(np.clip(f, 0, self.storyboard.length - 1)) for f in span)
            span = (lo, hi) if hi > lo else None
        if span != self.span:
            self.span = span
            self.spanChanged.emit()

    def span_or(self, default: tuple[int, int]) -> tuple[int, int]:
        return self.span if self.span is not None else default

    def set_settings(self, settings: GenerationSettings) -> None:
        if settings != self.settings:
            self.settings = settings
            self.settingsChanged.emit()

    # ---- generation results ------------------------------------------------------------------
    def set_result(self, clips: list[MotionClip], phase: np.ndarray | None,
                   source: Storyboard | None = None, preview: bool = False) -> None:
        """Motion that is no take (a drag's preview, a recovered clip); source: the storyboard the
        clips were generated from (None: the current one)."""
        self.take_index, self.result_is_preview = -1, preview
        self.clips, self.variation = list(clips), 0
        self.phase = phase if phase is not None else (clips[0].phase if clips else None)
        self._result_source = (source or self.storyboard).to_json() if clips else None
        self.resultChanged.emit()

    @property
    def result_outdated(self) -> bool:
        """A result is shown and the storyboard differs from the one it came from (an edit made
        since, or during its generation, and not undone)."""
        return self._result_source is not None and self._result_source != self.storyboard.to_json()

    def add_take(self, take: Take) -> None:
        """A finished generation: kept (the oldest beyond MAX_TAKES dropped), shown, and unsaved.
        The generation after a drag replaces the newest take if that came after a drag too: a
        session of posing leaves one take, not one per release."""
        drafts = take.settings.get("after_drag") and self.takes and self.takes[-1].settings.get("after_drag")
        self.takes = (self.takes[:-1] if drafts else self.takes) + [take]
        self.takes = self.takes[-MAX_TAKES:]
        self._unsaved_without_edits = True
        self.choose_take(len(self.takes) - 1, force=True, restore_settings=False)   # the panel may have moved on
        self._emit_dirty()

    def set_takes(self, takes: list[Take]) -> None:
        """The takes of a reopened storyboard; the newest is shown."""
        self.takes = list(takes)[-MAX_TAKES:]
        self.choose_take(len(self.takes) - 1, force=True)

    def choose_take(self, index: int, force: bool = False, restore_settings: bool = True) -> None:
        """Show take `index`; the generation settings become the ones it was made with."""
        if 0 <= index < len(self.takes) and (force or index != self.take_index):
            take = self.takes[index]
            self.clips, self.variation = list(take.clips), take.chosen
            self.phase = take.clip.phase
            self._result_source = take.source
            self.take_index, self.result_is_preview = index, False
            if restore_settings:
                self.set_settings(settings_of(take.settings, self.settings))
            self.resultChanged.emit()

    def choose_variation(self, index: int) -> None:
        """Show variation `index`; it becomes the one its take keeps."""
        if 0 <= index < len(self.clips) and index != self.variation:
            self.variation = index
            if self.clips[index].phase is not None:
                self.phase = self.clips[index].phase
            if 0 <= self.take_index < len(self.takes) and self.takes[self.take_index].chosen != index:
                self.takes[self.take_index].chosen = index
                self._unsaved_without_edits = True
                self._emit_dirty()
            self.resultChanged.emit()

    @property
    def clip(self) -> MotionClip | None:
        """The generated clip currently shown (the chosen variation), if any."""
        return self.clips[self.variation] if self.clips else None

    def set_reference(self, clip: MotionClip | None) -> None:
        self.reference = clip
        self.referenceChanged.emit()
