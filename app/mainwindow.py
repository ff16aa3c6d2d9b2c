"""The main window: canvas in the middle, timeline + phase strip, 3D view, floor plan and properties in
docks; menus, toolbar, status bar and shortcuts; generation (files, exports and recovery are
files.py's, keypose actions pose_actions.py's, the live preview live_preview.py's).

Every failure a person can cause (a bad file, a full disk, a sampler error) becomes a dialog
with a one-line message, and the document stays as it was.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QEvent, QSettings, Qt
from PySide6.QtGui import QAction, QActionGroup, QKeySequence
from PySide6.QtWidgets import (QDockWidget, QFrame, QHBoxLayout, QLabel, QMainWindow, QProgressBar, QScrollArea,
                               QSizePolicy, QVBoxLayout, QWidget)

from engine.storyboard import Storyboard

from . import commands as cmd
from .autosave import Autosaver
from .canvas import SketchCanvas
from .document import OBJECT_PATH, TOOLS, Document
from .examples import list_examples
from .files import APP_NAME, FileActions
from .generation_actions import GenerationActions
from .floor_plan import FloorPlan
from .generation import GenerationSettings, StepStream, start_generation
from .live_preview import LivePreview
from .phase_strip import PhaseStrip, phase_legend_html
from .pose_actions import PoseActions
from .playback import SPEEDS, Playback, speed_label
from .properties import PropertiesPanel
from .shortcuts import WindowShortcutsFirst
from .session import GenerationSession
from .timeline import PlaybackControls, Timeline
from .toolbar import MainToolbar
from .view_options import LABELS as VIEW_LABELS
from .view_options import ViewOptions, ViewOptionsModel
from .viewport import Viewport

GEOMETRY_KEY, DOCKS_KEY = "window/geometry", "window/docks"
LAYOUT_VERSION = 2                   # bump when the docks change: an older saved layout is ignored
TOOL_KEYS = {"select": "V", "keypose": "K", "trajectory": "T", "object": "O", "contact": "C", "erase": "E"}
TOOL_TIPS = {"select": "Select and move joints and objects",
             "keypose": "Click to place a stick figure at the playhead; drag joints to pose it",
             "trajectory": "Draw a path for the selected joint; start on an existing path to redraw part of it",
             "object": "Drag a rectangle (or draw a lasso) for the object at the playhead",
             "contact": "Click a hand, then an object anchor or another hand",
             "erase": "Click a joint, path, contact or object to remove it"}


class VerticalScroll(QScrollArea):
    """Scrolls a panel up and down, never sideways: as wide as the panel needs (plus the scroll
    bar), as short as a laptop screen leaves it."""

    def __init__(self, panel: QWidget):
        super().__init__()
        self.setWidget(panel)
        self.setWidgetResizable(True)
        self.setFrameShape(QFrame.NoFrame)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
        panel.installEventFilter(self)
        self._fit_width()

    def eventFilter(self, watched, event) -> bool:
        if event.type() == QEvent.LayoutRequest:  # e.g. a combo box got longer names
            self._fit_width()
        return False

    def _fit_width(self) -> None:
        self.setMinimumWidth(self.widget().minimumSizeHint().width() + self.verticalScrollBar().sizeHint().width())


class MainWindow(FileActions, PoseActions, GenerationActions, QMainWindow):
    def __init__(self, data_dir: Path, settings: QSettings | None = None,
                 generate: Callable[[Storyboard, GenerationSettings], StepStream] = start_generation,
                 autosave_delay_ms: int = 400):
        super().__init__()
        self.doc = Document()
        self.settings = settings or QSettings()
        self.playback = Playback(self.doc, self)
        self.session = GenerationSession(self.doc, generate, self)
        self.view_options = ViewOptionsModel(self.settings, self)
        self.autosaver = Autosaver(self.doc, data_dir, autosave_delay_ms, self)

        self.canvas = SketchCanvas(self.doc)
        self.setCentralWidget(self.canvas)
        self.floor_plan = FloorPlan(self.doc)
        self.timeline = Timeline(self.doc)
        self.phase_strip = PhaseStrip(self.doc)
        self.viewport = Viewport()
        self.viewport.empty_hint = "No motion yet.\nSketch, then press \u25b6 Generate (Ctrl+Enter)."
        self.properties = PropertiesPanel(self.doc)
        self.live_preview = LivePreview((self.canvas, self.floor_plan), self.session, self.generation_settings,
                                        lambda: self.generate(after_drag=True), self.settings, self)
        self._build_actions()
        self._shortcuts_first = WindowShortcutsFirst(self)
        self._build_docks()
        self._build_menus()
        self._build_toolbar()
        self._build_status()
        self._connect()
        self._restore_layout()
        self.setAcceptDrops(True)
        self._update_title()

    # ---- construction ------------------------------------------------------------------------
    def _action(self, text: str, slot, shortcut=None, tip: str = "", enabled: bool = True) -> QAction:
        action = QAction(text, self)
        if shortcut is not None:
            action.setShortcuts(shortcut if isinstance(shortcut, list) else [QKeySequence(shortcut)])
        if tip:
            action.setToolTip(tip)
            action.setStatusTip(tip)
        action.setEnabled(enabled)
        if slot is not None:
            action.triggered.connect(slot)
        self.addAction(action)   # shortcuts work even when the action is in no visible menu
        return action

    def _build_actions(self) -> None:
        a = self._action
        self.act_new = a("&New", self.new_document, QKeySequence.New)
        self.act_open = a("&Open\u2026", lambda: self.open_file(), QKeySequence.Open)
        self.act_save = a("&Save", self.save, QKeySequence.Save)
        self.act_save_as = a("Save &As\u2026", self.save_as, QKeySequence("Ctrl+Shift+S"))
        self.act_export_npz = a("Export Motion (NPZ)\u2026", self.export_npz, tip="Save the generated motion")
        self.act_export_bvh = a("Export Motion (BVH)\u2026", self.export_bvh, tip="One BVH file per person")
        self.act_export_gltf = a("Export Scene (glTF)\u2026", self.export_gltf,
                                 tip="Animated people and objects as one .glb for Blender and other tools")
        self.act_export_object_path = a("Export Object Path (CSV)\u2026", self.export_object_path,
                                        tip="Each object's position, rotation and grip points per frame")
        self.act_export_png = a("Export 3D View (PNG)\u2026", self.export_png)
        self.act_import_bvh = a("Import Reference Motion (BVH)\u2026", lambda: self.import_bvh(),   # not triggered's bool
                                tip="Show real motion under the sketch (one BVH file per person)")
        self.act_trace = a("Trace Storyboard from Motion", self.trace_storyboard,
                           tip="Start a new storyboard drawn from the reference (or generated) motion")
        self.act_quit = a("&Quit", self.close, QKeySequence.Quit)

        stack = self.doc.undo_stack
        self.act_undo, self.act_redo = stack.createUndoAction(self, "&Undo"), stack.createRedoAction(self, "&Redo")
        self.act_undo.setShortcuts([QKeySequence.Undo])
        self.act_redo.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence("Ctrl+Y")])
        for action, label in ((self.act_undo, "Undo"), (self.act_redo, "Redo")):
            action.setIconText(label)   # the toolbar's button keeps its width; its tooltip names the edit
        self.addActions([self.act_undo, self.act_redo])
        self.act_copy_pose = a("Copy Previous Keypose", self.copy_previous_keypose, QKeySequence("Ctrl+D"),
                               tip="Pose the selected agent at the playhead like its previous keyframe")
        self.act_copy = a("Copy Pose", self.copy_pose, QKeySequence.Copy,
                          tip="Copy the selected agent's keypose at the playhead")
        self.act_paste = a("Paste Pose", self.paste_pose, QKeySequence.Paste,
                           tip="Pose the selected agent at the playhead like the copied pose, where it stands")
        self.act_mirror = a("Mirror Keypose", self.mirror_keypose, QKeySequence("M"),
                            tip="Flip the selected agent's keypose at the playhead left-right")
        self.act_delete_key = a("Delete Keypose", self.delete_keypose, QKeySequence.Delete,
                                tip="Delete the selected agent's keypose at the playhead")
        self.act_pin = a("Pin Joint", lambda: self.doc.toggle_pin(self.doc.selection.agent, self.doc.selection.joint),
                         QKeySequence("P"),
                         tip="Pin the selected joint: it stays put while the pose is dragged (P again unpins)")

        self.tool_group = QActionGroup(self)
        self.tool_actions: dict[str, QAction] = {}
        for tool in TOOLS:
            act = a(tool.capitalize(), lambda _=False, t=tool: self.doc.set_tool(t), QKeySequence(TOOL_KEYS[tool]),
                    tip=f"{TOOL_TIPS[tool]}  ({TOOL_KEYS[tool]})")
            act.setCheckable(True)
            self.tool_group.addAction(act)
            self.tool_actions[tool] = act
        self.tool_actions[self.doc.tool].setChecked(True)

        self.act_play = a("Play / Pause", self.playback.toggle, QKeySequence(Qt.Key_Space))
        self.act_next = a("Next Frame", lambda: self.playback.step(1), QKeySequence(Qt.Key_Right))
        self.act_prev = a("Previous Frame", lambda: self.playback.step(-1), QKeySequence(Qt.Key_Left))
        self.act_first = a("First Frame", lambda: self.doc.set_frame(0), QKeySequence(Qt.Key_Home))
        self.act_last = a("Last Frame", lambda: self.doc.set_frame(self.doc.storyboard.length - 1), QKeySequence(Qt.Key_End))
        self.act_next_key = a("Next Key", lambda: self.playback.to_key(1), QKeySequence(Qt.Key_PageDown))
        self.act_prev_key = a("Previous Key", lambda: self.playback.to_key(-1), QKeySequence(Qt.Key_PageUp))
        self.act_loop = a("Loop", self.playback.set_loop, tip="Loop playback; off, it stops at the last frame")
        self.act_loop.setCheckable(True)
        self.act_loop.setChecked(self.playback.loop)
        self.speed_group = QActionGroup(self)
        self.speed_actions: dict[float, QAction] = {}
        for speed in SPEEDS:
            act = a(speed_label(speed), lambda _=False, s=speed: self.playback.set_speed(s))
            act.setCheckable(True)
            self.speed_group.addAction(act)
            self.speed_actions[speed] = act
        self.speed_actions[self.playback.speed].setChecked(True)
        self.act_generate = a("\u25b6  Generate", self.generate, [QKeySequence("Ctrl+Return"), QKeySequence("Ctrl+Enter")],
                              tip="Generate motion from the storyboard (Ctrl+Enter)")
        self.act_cancel = a("\u25a0  Cancel", self._cancel, QKeySequence(Qt.Key_Escape),
                            tip="Stop the running generation (Esc)", enabled=False)
        self.act_live = a("&Live Preview While Dragging", self.live_preview.set_enabled,
                          tip="While a joint or an object is dragged, a quick preview follows the pointer; "
                              "the full generation follows the release")
        self.act_live.setCheckable(True)
        self.act_live.setChecked(self.live_preview.enabled)
        # Overlays an artist may want out of the way while judging the motion itself.
        self.view_actions: dict[str, QAction] = {}
        for name, label in VIEW_LABELS.items():
            act = a(label, lambda on, name=name: self.view_options.set(**{name: on}))
            act.setCheckable(True)
            act.setChecked(getattr(self.view_options.options, name))
            self.view_actions[name] = act
        self.view_actions["onion"].setToolTip("Show the generated motion under the sketch")

    def _build_docks(self) -> None:
        self.setDockOptions(QMainWindow.AnimatedDocks | QMainWindow.AllowNestedDocks)
        timeline_panel = QWidget()
        column = QVBoxLayout(timeline_panel)
        column.setContentsMargins(0, 0, 0, 0)
        column.setSpacing(0)
        header = QHBoxLayout()
        header.setContentsMargins(6, 2, 6, 2)
        self.playback_controls = PlaybackControls(self.playback)
        self.frame_label = QLabel()
        header.addWidget(self.playback_controls)
        header.addSpacing(8)
        header.addWidget(self.frame_label)
        header.addSpacing(16)
        header.addWidget(QLabel(phase_legend_html()))
        header.addSpacing(16)
        hint = QLabel("shift-drag: span \u00b7 double-click: add key \u00b7 right-click: delete")
        hint.setStyleSheet("color: #8a857a;")
        hint.setToolTip(hint.text())
        hint.setMinimumWidth(0)      # clipped on a narrow window rather than widening it
        hint.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Preferred)
        header.addWidget(hint, 1)
        column.addLayout(header)
        column.addWidget(self.timeline)
        column.addWidget(self.phase_strip, 1)
        self.timeline_dock = self._dock("Timeline", timeline_panel, Qt.BottomDockWidgetArea)
        self.viewport_dock = self._dock("3D View", self.viewport, Qt.RightDockWidgetArea)
        self.floor_plan_dock = self._dock("Floor Plan", self.floor_plan, Qt.RightDockWidgetArea)
        self.tabifyDockWidget(self.viewport_dock, self.floor_plan_dock)
        self.viewport_dock.raise_()
        self.properties_dock = self._dock("Properties", VerticalScroll(self.properties), Qt.LeftDockWidgetArea)
        self.resizeDocks([self.viewport_dock], [440], Qt.Horizontal)
        self.resizeDocks([self.properties_dock], [250], Qt.Horizontal)
        self.resizeDocks([self.timeline_dock], [210], Qt.Vertical)

    def _dock(self, title: str, widget: QWidget, area) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(title)
        dock.setWidget(widget)
        dock.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable
                         | QDockWidget.DockWidgetClosable)
        self.addDockWidget(area, dock)
        return dock

    def _restore_layout(self) -> None:
        """The window's size, place and docks as they were when it last closed. The first time,
        1360 x 860, or maximized on a screen with less room (a 1366 x 768 laptop: its panel and
        the title bar come off the 768)."""
        geometry, state = self.settings.value(GEOMETRY_KEY), self.settings.value(DOCKS_KEY)
        if geometry is not None and self.restoreGeometry(geometry):  # Qt moves it onto a screen
            if state is not None:
                self.restoreState(state, LAYOUT_VERSION)
            return
        screen = self.screen().availableGeometry()
        self.resize(min(1360, screen.width()), min(860, screen.height()))
        if screen.width() < 1360 + 40 or screen.height() < 860 + 60:
            self.setWindowState(Qt.WindowMaximized)

    def save_layout(self) -> None:
        self.settings.setValue(GEOMETRY_KEY, self.saveGeometry())
        self.settings.setValue(DOCKS_KEY, self.saveState(LAYOUT_VERSION))

    def _build_menus(self) -> None:
        bar = self.menuBar()
        files = bar.addMenu("&File")
        files.setToolTipsVisible(True)
        files.addActions([self.act_new, self.act_open])
        self.recent_menu = files.addMenu("Open &Recent")
        self.examples_menu = files.addMenu("Open E&xample")
        self.examples_menu.setToolTipsVisible(True)
        for example in list_examples():
            action = self.examples_menu.addAction(example.label, lambda p=example.path: self.open_example(p))
            action.setToolTip(example.path.name)
        self.examples_menu.setEnabled(not self.examples_menu.isEmpty())
        files.addSeparator()
        files.addActions([self.act_save, self.act_save_as])
        files.addSeparator()
        files.addActions([self.act_export_npz, self.act_export_bvh, self.act_export_gltf,
                          self.act_export_object_path, self.act_export_png])
        files.addSeparator()
        files.addActions([self.act_import_bvh, self.act_trace])
        files.addSeparator()
        files.addAction(self.act_quit)
        edit = bar.addMenu("&Edit")
        edit.addActions([self.act_undo, self.act_redo])
        edit.addSeparator()
        edit.addActions([self.act_copy, self.act_paste, self.act_copy_pose, self.act_mirror, self.act_pin, self.act_delete_key])
        self.build_pose_library(edit.addMenu("Stamp &Pose"))
        tools = bar.addMenu("&Tools")
        tools.addActions(list(self.tool_actions.values()))
        play = bar.addMenu("&Playback")
        play.addActions([self.act_play, self.act_prev, self.act_next, self.act_prev_key, self.act_next_key,
                         self.act_first, self.act_last])
        play.addSeparator()
        play.addAction(self.act_loop)
        speed_menu = play.addMenu("&Speed")
        speed_menu.addActions(list(self.speed_actions.values()))
        gen = bar.addMenu("&Generate")
        gen.addActions([self.act_generate, self.act_cancel])
        gen.addSeparator()
        gen.addAction(self.act_live)
        self.threads_menu = gen.addMenu("CPU &Threads")
        self._build_threads_menu(self.threads_menu)
        view = bar.addMenu("&View")
        view.addActions(list(self.view_actions.values()))
        view.addSeparator()
        for dock in (self.timeline_dock, self.viewport_dock, self.floor_plan_dock, self.properties_dock):
            view.addAction(dock.toggleViewAction())
        self._rebuild_recent()

    def _build_toolbar(self) -> None:
        self.toolbar = MainToolbar(self, [list(self.tool_actions.values()), [self.act_copy_pose, self.act_mirror],
                                          [self.act_undo, self.act_redo]], [self.act_generate, self.act_cancel],
                                   {self.act_copy_pose: "Copy Key", self.act_mirror: "Mirror",
                                    self.act_undo: "\u21b6", self.act_redo: "\u21b7"})

    def _build_status(self) -> None:
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(220)
        self.progress.setTextVisible(True)
        self.progress.setFormat("step %v / %m")
        self.progress.hide()
        self.statusBar().addPermanentWidget(self.progress)
        self.statusBar().showMessage("Ready. Pick a tool and sketch; Ctrl+Enter generates.")

    def _connect(self) -> None:
        doc = self.doc
        doc.dirtyChanged.connect(lambda _: self._update_title())
        doc.pathChanged.connect(self._update_title)
        doc.toolChanged.connect(lambda tool: self.tool_actions[tool].setChecked(True))
        doc.toolChanged.connect(self._say_what_a_path_is_for)
        doc.frameChanged.connect(self._on_frame)
        doc.storyboardChanged.connect(self._on_storyboard)
        doc.resultChanged.connect(self._show_result)
        self.viewport.playToggleRequested.connect(self.playback.toggle)
        self.viewport.stepRequested.connect(self.playback.step)
        for view in (self.canvas, self.floor_plan):
            view.message.connect(lambda text: self.statusBar().showMessage(text, 5000))
        self.floor_plan.dragEnded.connect(self._keep_selected_figure_in_view)
        self.playback.loopChanged.connect(self.act_loop.setChecked)
        self.playback.speedChanged.connect(self._on_speed)
        self.view_options.changed.connect(self._apply_view_options)
        self._apply_view_options(self.view_options.options)
        # The views observe the generation session: previews and phases while it runs; a new
        # result reaches them through the document, and a cancel or a failure shows its last one.
        session = self.session
        session.stepped.connect(lambda event: self.viewport.set_preview(event.preview))
        session.stepped.connect(lambda event: self.phase_strip.set_phase(event.phase))
        session.stepped.connect(self._show_progress)
        for stopped in (session.failed, session.cancelled):
            stopped.connect(lambda *_: self.viewport.set_preview(self.doc.clip))
            stopped.connect(lambda *_: self.phase_strip.show_document_phase())
        session.outdatedChanged.connect(self._update_notice)
        doc.resultChanged.connect(self._update_notice)
        session.runningChanged.connect(self._on_running)
        session.finished.connect(self._on_generated)
        session.failed.connect(self._on_failed)
        session.cancelled.connect(lambda: self.statusBar().showMessage("Generation cancelled.", 5000))
        self._on_storyboard()
        self._on_frame(doc.frame)

    # ---- document observers ------------------------------------------------------------------
    def _update_title(self) -> None:
        name = self.doc.path.name if self.doc.path else "Untitled"
        self.setWindowTitle(f"{name}[*] \u2014 {APP_NAME}")
        self.setWindowModified(self.doc.dirty)

    def _on_frame(self, frame: int) -> None:
        sb = self.doc.storyboard
        self.frame_label.setText(f"frame <b>{frame}</b> / {sb.length - 1}   \u00b7   {sb.length} frames @ {sb.fps:g} fps")
        self.viewport.set_frame(frame)

    def _on_speed(self, speed: float) -> None:
        for rate, action in self.speed_actions.items():
            action.setChecked(rate == speed)   # none checked for a rate the menu does not offer

    def _on_storyboard(self) -> None:
        self._drop_stale_summary()
        self.viewport.set_storyboard(self.doc.storyboard)
        self._on_frame(self.doc.frame)

    def _show_result(self) -> None:
        """A new clip reframes the 3D camera (set_clip); the playhead stays where the artist left it."""
        self.viewport.set_clip(self.doc.clip)
        self.viewport.set_frame(self.doc.frame)

    def _apply_view_options(self, options: ViewOptions) -> None:
        self.canvas.set_onion(options.onion)
        self.viewport.set_scene_options(options.scene(self.viewport.options))
        for name, action in self.view_actions.items():
            action.setChecked(getattr(options, name))

    def _say_what_a_path_is_for(self, tool: str) -> None:
        """The Trajectory tool draws for the selected joint, which the last dragged one becomes:
        said when the tool is picked (a wrist's path drawn for a pelvis's went unnoticed)."""
        sel = self.doc.selection
        if tool == "trajectory" and sel.agent is not None:
            whose = "the object's" if sel.joint == OBJECT_PATH else f"{sel.agent}'s {sel.joint}"
            self.statusBar().showMessage(f"Trajectory: draws {whose} path (Properties > Joint picks another).", 8000)

    def _keep_selected_figure_in_view(self) -> None:
        key = cmd.find_keypose(self.doc.storyboard, self.doc.selection.agent, self.doc.frame)
        if key is not None:
            self.canvas.keep_in_view(key.points[key.mask])

    # ---- closing ---------------------------------------------------------------------------------
    def closeEvent(self, event) -> None:
        if not self.maybe_save():
            event.ignore()
            return
        self.save_layout()
        self.shutdown()
        event.accept()

    def shutdown(self) -> None:
        """Stop playback, the generation thread and autosave; the recovery file goes too, since
        the person has either saved or chosen to discard."""
        self.playback.pause()
        self.session.shutdown()
        self.autosaver.stop()
