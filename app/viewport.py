"""The 3D viewport: a plain QWidget that paints images from engine.render's SceneRenderer.

No QOpenGLWidget (DESIGN section 5): the renderer draws with the process's one standalone EGL
context into its own framebuffer, and this widget paints the pixels. It re-renders only when
something it shows changed (clip, frame, camera, size, storyboard), on the next paint: however
many previews stream in between two paints, only the newest is drawn.
The renderer is built and its shaders compiled just after the first paint (warm_up), so the
second of shader compiling falls at start-up, not on a generation's first preview.

Public API (everything else is private):
    Viewport(parent=None, config: RenderConfig | None = None)
    set_clip(clip: MotionClip | None)      show a motion; frames the camera on it; frame 0
    set_preview(clip: MotionClip)          slot for streamed previews: same, but keeps the frame
                                           and the camera
    warm_up()                              build the renderer and compile its shaders now
    set_storyboard(sb: Storyboard | None)  keyframe ghosts and target paths come from it
    set_frame(frame: int)                  clamped to the clip; emits frameChanged when it moves
    frame -> int, num_frames -> int
    play(), pause(), toggle_playback(), step(frames: int = 1)
    loop: bool (default True), speed: float (playback rate, default 1.0)
    frame_all()                            aim the camera at everything (also the F key)
    camera: OrbitCamera                    change it, then call update_view()
    empty_hint: str                        shown over the ground while there is no clip
    grab_png(path) -> bool                 save what the widget shows
Signals: frameChanged(int), playingChanged(bool).
Mouse: left drag orbits, middle drag or shift + left drag pans, wheel zooms.
Keys: F frames all, Space plays / pauses, Left / Right step one frame.
"""
from __future__ import annotations

from PySide6.QtCore import QPointF, Qt, QTimer, Signal, Slot
from PySide6.QtGui import QColor, QImage, QPainter
from PySide6.QtWidgets import QWidget

from engine.clip import MotionClip
from engine.render import OrbitCamera, RenderConfig, RenderUnavailableError, SceneRenderer, scene_from_clip
from engine.storyboard import Storyboard

ORBIT_DEGREES_PER_PIXEL = 0.4
WHEEL_ZOOM_PER_NOTCH = 0.88  # distance factor per 120 units of wheel angle


class Viewport(QWidget):
    frameChanged = Signal(int)
    playingChanged = Signal(bool)

    def __init__(self, parent: QWidget | None = None, config: RenderConfig | None = None):
        super().__init__(parent)
        self.setFocusPolicy(Qt.StrongFocus)
        self.setMinimumSize(160, 120)
        self.camera = OrbitCamera()
        self.loop = True
        self.empty_hint = ""
        self._speed = 1.0
        self._config = config
        self._renderer: SceneRenderer | None = None
        self._warm = False
        self._error = ""
        self._clip: MotionClip | None = None
        self._storyboard: Storyboard | None = None
        self._frame = 0
        self._image: QImage | None = None
        self._pixels = None  # the renderer's buffer that _image points into
        self._dirty = True
        self._drag_pos: QPointF | None = None
        self._drag_mode: str | None = None  # "orbit" or "pan" while a button is held
        self._timer = QTimer(self)
        self._timer.setTimerType(Qt.PreciseTimer)
        self._timer.timeout.connect(self._advance)

    # ---- content -------------------------------------------------------------------------
    @property
    def frame(self) -> int:
        return self._frame

    @property
    def num_frames(self) -> int:
        return 0 if self._clip is None else self._clip.num_frames

    def set_clip(self, clip: MotionClip | None) -> None:
        self._clip = clip
        self._frame = -1  # force the signal for frame 0
        self.set_frame(0)
        self.frame_all()
        self._restart_timer()

    @Slot(object)
    def set_preview(self, clip: MotionClip) -> None:
        self._clip = clip
        self.set_frame(self._frame)
        self.update_view()

    def set_storyboard(self, storyboard: Storyboard | None) -> None:
        self._storyboard = storyboard
        self.update_view()

    @Slot(int)
    def set_frame(self, frame: int) -> None:
        frame = min(max(int(frame), 0), max(self.num_frames - 1, 0))
        if frame != self._frame:
            self._frame = frame
            self.frameChanged.emit(frame)
            self.update_view()

    def frame_all(self) -> None:
        scene = scene_from_clip(self._clip, self._frame, self._storyboard)
        if self._clip is not None:
            scene.people = self._clip.joints.reshape(-1, 22, 3)  # the whole motion, not one frame
        self.camera.frame_all(scene.bounds(), self.width() / max(1, self.height()))
        self.update_view()

    def update_view(self) -> None:
        """Mark the picture stale; it is re-rendered at the next paint."""
        self._dirty = True
        self.update()

    # ---- playback ------------------------------------------------------------------------
    @property
    def speed(self) -> float:
        return self._speed

    @speed.setter
    def speed(self, rate: float) -> None:
        self._speed = max(float(rate), 1e-3)
        self._restart_timer(start=self.playing)

    @property
    def playing(self) -> bool:
        return self._timer.isActive()

    def play(self) -> None:
        if self.num_frames < 2 or self.playing:
            return
        if self._frame >= self.num_frames - 1 and not self.loop:
            self.set_frame(0)
        self._restart_timer(start=True)
        self.playingChanged.emit(True)

    def pause(self) -> None:
        if self.playing:
            self._timer.stop()
            self.playingChanged.emit(False)

    def toggle_playback(self) -> None:
        self.pause() if self.playing else self.play()

    def step(self, frames: int = 1) -> None:
        n = self.num_frames
        if n:
            target = self._frame + frames
            self.set_frame(target % n if self.loop else target)

    def _restart_timer(self, start: bool = False) -> None:
        if self._clip is not None:
            self._timer.setInterval(max(1, round(1000.0 / (self._clip.fps * self._speed))))
        if start:
            self._timer.start()

    def _advance(self) -> None:
        if self._frame >= self.num_frames - 1 and not self.loop:
            self.pause()
            return
        self.step(1)

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
                             f"frame {self._frame} / {self.num_frames - 1}")
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
            pixels = self._renderer.render(scene_from_clip(self._clip, self._frame, self._storyboard), self.camera)
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
            self.toggle_playback()
        elif key == Qt.Key_Right:
            self.step(1)
        elif key == Qt.Key_Left:
            self.step(-1)
        else:
            super().keyPressEvent(event)
