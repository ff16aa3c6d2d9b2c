"""The 3D viewport: a plain QWidget that paints images from engine.render's SceneRenderer.

No QOpenGLWidget (DESIGN section 5): the renderer draws with the process's one standalone EGL
context into its own framebuffer, and this widget paints the pixels. It re-renders only when
something it shows changed (clip, frame, camera, size, storyboard), on the next paint: however
many previews stream in between two paints, only the newest is drawn.
The renderer is built and its shaders compiled just after the first paint (warm_up), so the
second of shader compiling falls at start-up, not on a generation's first preview.
It is a view of the playhead, not a clock: it shows the frame it is given (set_frame), and its
playback keys only ask for changes (playToggleRequested, stepRequested), which the owner of
the playback model (app.playback.Playback) answers.

Public API (everything else is private):
    Viewport(parent=None, config: RenderConfig | None = None)
    set_clip(clip: MotionClip | None)      show a motion; frames the camera on it; frame 0
    set_preview(clip: MotionClip)          slot for streamed previews: same, but keeps the frame
                                           and the camera
    warm_up()                              build the renderer and compile its shaders now
    set_storyboard(sb: Storyboard | None)  keyframe ghosts and target paths come from it
    set_frame(frame: int)                  the playhead; shown clamped to the clip (see frame)
    frame -> int, num_frames -> int
    frame_all()                            aim the camera at everything (also the F key)
    camera: OrbitCamera                    change it, then call update_view()
    empty_hint: str                        shown over the ground while there is no clip
    grab_png(path) -> bool                 save what the widget shows
Signals: playToggleRequested(), stepRequested(frames: int).
Mouse: left drag orbits, middle drag or shift + left drag pans, wheel zooms.
Keys: F frames all; Space requests play / pause, Left / Right request a one-frame step.
"""
from __future__ import annotations

from dataclasses import replace

from PySide6.QtCore import QPointF, Qt, QTimer, Signal, Slot
from PySide6.QtGui import QColor, QImage, QPainter
from PySide6.QtWidgets import QWidget

from engine.clip import MotionClip
from engine.render import (OrbitCamera, RenderConfig, RenderUnavailableError, SceneOptions, SceneRenderer,
                           scene_from_clip)
from engine.storyboard import Storyboard

ORBIT_DEGREES_PER_PIXEL = 0.4
WHEEL_ZOOM_PER_NOTCH = 0.88  # distance factor per 120 units of wheel angle


class Viewport(QWidget):
    playToggleRequested = Signal()
    stepRequested = Signal(int)

    def __init__(self, parent: QWidget | None = None, config: RenderConfig | None = None):
        super().__init__(parent)
        self.setFocusPolicy(Qt.StrongFocus)
        self.setMinimumSize(160, 120)
        self.camera = OrbitCamera()
        self.empty_hint = ""
        self._config = config
        self._renderer: SceneRenderer | None = None
        self._warm = False
        self._error = ""
        self._clip: MotionClip | None = None
        self._storyboard: Storyboard | None = None
        self._playhead = 0  # the frame asked for; shown clamped to the clip (see frame)
        self._image: QImage | None = None
        self._pixels = None  # the renderer's buffer that _image points into
        self._dirty = True
        self.options = SceneOptions()  # which overlays (ghosts, target and generated paths) to draw
        self._drag_pos: QPointF | None = None
        self._drag_mode: str | None = None  # "orbit" or "pan" while a button is held

    # ---- content -------------------------------------------------------------------------
    @property
    def frame(self) -> int:
        """The frame shown: the playhead, clamped to the clip (a shorter preview keeps the
        playhead for the next, longer one)."""
        return min(self._playhead, max(self.num_frames - 1, 0))

    @property
    def num_frames(self) -> int:
        return 0 if self._clip is None else self._clip.num_frames

    def set_clip(self, clip: MotionClip | None) -> None:
        self._clip = clip
        self._playhead = 0
        self.frame_all()

    @Slot(object)
    def set_preview(self, clip: MotionClip) -> None:
        self._clip = clip
        self.update_view()

    def set_storyboard(self, storyboard: Storyboard | None) -> None:
        self._storyboard = storyboard
        self.update_view()

    def set_options(self, **overlays: bool) -> None:
        """Show or hide overlays by SceneOptions field, e.g. set_options(ghosts=False)."""
        self.options = replace(self.options, **overlays)
        self.update_view()

    @Slot(int)
    def set_frame(self, frame: int) -> None:
        shown = self.frame
        self._playhead = max(int(frame), 0)
        if self.frame != shown:
            self.update_view()

    def frame_all(self) -> None:
        scene = scene_from_clip(self._clip, self.frame, self._storyboard, self.options)
        if self._clip is not None:
            scene.people = self._clip.joints.reshape(-1, 22, 3)  # the whole motion, not one frame
        self.camera.frame_all(scene.bounds(), self.width() / max(1, self.height()))
        self.update_view()

    def update_view(self) -> None:
        """Mark the picture stale; it is re-rendered at the next paint."""
        self._dirty = True
        self.update()

    # ---- output --------------------------------------------------------------------------
    def grab_png(self, path: str) -> bool:
        """Save the widget as it looks now (the 3D image and its overlay text)."""
        return self.grab().save(str(path), "PNG")

    def warm_up(self) -> None:
        """Build the renderer and let it compile every shader now (about a second of software GL
        the first time in a process). Does nothing once done."""
        if self._warm:
            return
        self._warm = True
        renderer = self._ensure_renderer()
        if renderer is not None:
            renderer.warm_up()
            self.update_view()  # the warm-up drew its own scene into the image we show

    def paintEvent(self, event) -> None:
        painter = QPainter(self)
        if self._dirty:
            self._render()
        if not self._warm:
            QTimer.singleShot(0, self, self.warm_up)  # once this first picture is on screen
        if self._image is None:
            painter.fillRect(self.rect(), QColor("#dfe3e8"))
            painter.drawText(self.rect(), Qt.AlignCenter | Qt.TextWordWrap, self._error or "3D view")
        else:
            painter.drawImage(0, 0, self._image)
        if self.num_frames:
            painter.setPen(QColor(60, 60, 60))
            painter.drawText(self.rect().adjusted(8, 6, -8, -6), Qt.AlignLeft | Qt.AlignTop,
                             f"frame {self.frame} / {self.num_frames - 1}")
        elif self.empty_hint and self._image is not None:
            self._paint_hint(painter)
        painter.end()

    def _paint_hint(self, painter: QPainter) -> None:
        """The empty-state hint on a soft card near the bottom, clear of the paths drawn mid-view."""
        area = self.rect().adjusted(16, 0, -16, -18)
        box = painter.boundingRect(area, Qt.AlignHCenter | Qt.AlignBottom | Qt.TextWordWrap, self.empty_hint)
        card = box.adjusted(-12, -8, 12, 8)
        painter.setRenderHint(QPainter.Antialiasing)
        painter.setPen(Qt.NoPen)
        painter.setBrush(QColor(255, 255, 255, 200))
        painter.drawRoundedRect(card, 6, 6)
        painter.setPen(QColor("#4a463f"))
        painter.drawText(box, Qt.AlignCenter | Qt.TextWordWrap, self.empty_hint)

    def _ensure_renderer(self) -> SceneRenderer | None:
        """The renderer at the widget's size; None (and the reason in _error) without OpenGL."""
        w, h = max(1, self.width()), max(1, self.height())
        try:
            if self._renderer is None:
                self._renderer = SceneRenderer(w, h, self._config)
            self._renderer.resize(w, h)
        except RenderUnavailableError as e:
            self._error, self._image = str(e), None
            return None
        return self._renderer

    def _render(self) -> None:
        self._dirty = False
        w, h = max(1, self.width()), max(1, self.height())
        if self._ensure_renderer() is None:
            return
        try:
            pixels = self._renderer.render(scene_from_clip(self._clip, self.frame, self._storyboard, self.options),
                                           self.camera)
        except RenderUnavailableError as e:
            self._error, self._image = str(e), None
            return
        # Wraps the renderer's buffer without a copy; it stays valid until the next render.
        self._image = QImage(pixels.data, w, h, 4 * w, QImage.Format_RGBA8888)
        self._pixels = pixels

    def resizeEvent(self, event) -> None:
        self.update_view()
        super().resizeEvent(event)

    # ---- interaction ---------------------------------------------------------------------
    def mousePressEvent(self, event) -> None:
        # The drag's meaning is fixed at the press: Shift pressed later does not switch modes.
        button, shift = event.button(), bool(event.modifiers() & Qt.ShiftModifier)
        if button == Qt.MiddleButton or (button == Qt.LeftButton and shift):
            self._drag_mode = "pan"
        elif button == Qt.LeftButton:
            self._drag_mode = "orbit"
        else:
            return
        self._drag_pos = event.position()
        self.setFocus()

    def mouseReleaseEvent(self, event) -> None:
        self._drag_pos = self._drag_mode = None

    def mouseMoveEvent(self, event) -> None:
        if self._drag_pos is None:
            return
        delta = event.position() - self._drag_pos
        self._drag_pos = event.position()
        if self._drag_mode == "pan":
            h = max(1, self.height())
            self.camera.pan(delta.x() / h, delta.y() / h)
        else:
            self.camera.orbit(-delta.x() * ORBIT_DEGREES_PER_PIXEL, delta.y() * ORBIT_DEGREES_PER_PIXEL)
        self.update_view()

    def wheelEvent(self, event) -> None:
        notches = event.angleDelta().y() / 120.0
        if notches:
            self.camera.zoom(WHEEL_ZOOM_PER_NOTCH ** notches)
            self.update_view()

    def keyPressEvent(self, event) -> None:
        key = event.key()
        if key == Qt.Key_F:
            self.frame_all()
        elif key == Qt.Key_Space:
            self.playToggleRequested.emit()
        elif key in (Qt.Key_Left, Qt.Key_Right):
            self.stepRequested.emit(1 if key == Qt.Key_Right else -1)
        else:
            super().keyPressEvent(event)
