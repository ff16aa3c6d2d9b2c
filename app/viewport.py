"""The 3D viewport: a plain QWidget that paints images from engine.render's SceneRenderer.

No QOpenGLWidget (DESIGN section 5): the renderer draws with the process's one standalone EGL
context into its own framebuffer, and this widget paints the pixels. It re-renders only when
something it shows changed (clip, frame, camera, size, storyboard), on the next turn of the
event loop, apart from painting: a render and the other widgets' paints then never add up to
one long wait, and however many previews stream in meanwhile, only the newest is drawn.
The first paint shows a placeholder; then the renderer is built and its shaders compiled
(warm_up), so the second of shader compiling neither holds up the window's first appearance
nor falls on a generation's first preview. While the camera moves (a drag, the wheel) the view
renders at MOVING_SCALE of its size, since sky, ground and ghosts are redrawn on every move,
and at full size again once the camera rests.
It is a view of the playhead, not a clock: it shows the frame it is given (set_frame), and its
playback keys only ask for changes (playToggleRequested, stepRequested), which the owner of
the playback model (app.playback.Playback) answers.

Public API (everything else is private):
    Viewport(parent=None, config: RenderConfig | None = None)
    set_clip(clip: MotionClip | None)      show a motion from frame 0; frames the camera on it
                                           where none was shown, or the last was all in view
                                           and this one leaves it
    set_preview(clip: MotionClip)          slot for streamed previews: same, but keeps the frame
                                           and the camera
    warm_up()                              build the renderer now; its shaders compile over the
                                           next turns of the event loop
    ready -> bool                          warm_up has finished: every shader is compiled
    rendered_size -> (int, int) | None     pixels of the last render (smaller while the camera moves)
    set_storyboard(sb: Storyboard | None)  keyframe ghosts and target paths come from it
    set_frame(frame: int)                  the playhead; shown clamped to the clip (see frame)
    frame -> int, num_frames -> int
    frame_all()                            aim the camera at everything (also the F key)
    camera: OrbitCamera                    change it, then call update_view()
    empty_hint: str                        shown over the ground while there is no clip
    set_notice(text: str)                  a line under the frame caption while a clip is shown
    set_scene_options(SceneOptions)        which overlays to draw
    draws_on_cpu() -> bool                 OpenGL runs in software (it competes with generation)
    grab_png(path) -> bool                 save what the widget shows
Signals: playToggleRequested(), stepRequested(frames: int).
Mouse: left drag orbits, middle drag or shift + left drag pans, wheel zooms.
Keys: F frames all; Space requests play / pause, Left / Right request a one-frame step.
"""
from __future__ import annotations

import threading

import numpy as np
from PySide6.QtCore import QBuffer, QByteArray, QIODevice, QPointF, Qt, QTimer, Signal, Slot
from PySide6.QtGui import QColor, QImage, QPainter
from PySide6.QtWidgets import QWidget

from engine.atomic import write_bytes
from engine.clip import MotionClip
from engine.objects import ObjectSpec
from engine.render import (OrbitCamera, RenderConfig, RenderUnavailableError, SceneOptions, SceneRenderer, is_software,
                           scene_from_clip, shared_context)
from engine.render.example import warm_up_scenes
from engine.storyboard import Storyboard

ORBIT_DEGREES_PER_PIXEL = 0.4
WHEEL_ZOOM_PER_NOTCH = 0.88  # distance factor per 120 units of wheel angle
MOVING_SCALE = 0.5           # render resolution while the camera moves (a quarter of the pixels)
CAMERA_REST_MS = 150         # after the last wheel step the view renders at full size again
PLACEHOLDER = QColor("#dfe3e8")
NOTICE_COLOR = "#b0451c"     # a burnt orange that reads on the sky and the ground


def _prefetch_object_meshes() -> threading.Thread:
    """Object meshes come from trimesh, whose import takes most of a second of Python: run it
    on a thread while the window appears, so that the GUI thread does not wait for it."""
    thread = threading.Thread(target=lambda: ObjectSpec("box").mesh(), name="mesh-import", daemon=True)
    thread.start()
    return thread


class Viewport(QWidget):
    playToggleRequested = Signal()
    stepRequested = Signal(int)

    def __init__(self, parent: QWidget | None = None, config: RenderConfig | None = None):
        super().__init__(parent)
        self.setFocusPolicy(Qt.StrongFocus)
        self.setMinimumSize(160, 120)
        self.camera = OrbitCamera()
        self.empty_hint = ""
        self.notice = ""
        self._config = config
        self._renderer: SceneRenderer | None = None
        self._warm = False   # warm_up has run: the renderer exists (or failed, see _error)
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
        self._render_timer = QTimer(self)
        self._render_timer.setSingleShot(True)
        self._render_timer.timeout.connect(self._render_if_stale)
        self._rest_timer = QTimer(self)  # runs while the wheel is turning the camera
        self._rest_timer.setSingleShot(True)
        self._rest_timer.timeout.connect(self.update_view)
        self._mesh_import = _prefetch_object_meshes()
        self._warm_up_steps: list = []  # example scenes still to draw (engine.render.example)

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
        """A new clip, from its first frame. The camera frames it where no motion was shown
        before, or where the last was all in view and this one leaves it; else it stays where it
        is: framed anew, the view moved with every live preview of a drag, and lost the artist's
        pan and zoom."""
        old, self._clip, self._playhead = self._clip, clip, 0
        aspect = self._aspect()
        if old is not None and clip is not None and (self.camera.sees(self._whole_scene_points(clip), aspect)
                                                     or not self.camera.sees(self._whole_scene_points(old), aspect)):
            self.update_view()
        else:
            self.frame_all()

    @Slot(object)
    def set_preview(self, clip: MotionClip) -> None:
        self._clip = clip
        self.update_view()

    def draws_on_cpu(self) -> bool:
        """Whether drawing runs on the CPU (software OpenGL), competing with generation for its
        cores: under Xvfb on 2 cores, a generation took 2.2 s with 2 torch threads, 1.0 s with 1."""
        try:
            return is_software(shared_context())
        except RenderUnavailableError:
            return False  # nothing is drawn

    def set_notice(self, text: str) -> None:
        if text != self.notice:
            self.notice = text
            self.update()   # text over the image: no new render

    def set_storyboard(self, storyboard: Storyboard | None) -> None:
        self._storyboard = storyboard
        self.update_view()

    def set_scene_options(self, options: SceneOptions) -> None:
        """Which overlays to draw (keyframe ghosts, sketched and generated paths)."""
        if options != self.options:
            self.options = options
            self.update_view()

    @Slot(int)
    def set_frame(self, frame: int) -> None:
        shown = self.frame
        self._playhead = max(int(frame), 0)
        if self.frame != shown:
            self.update_view()

    def frame_all(self) -> None:
        self.camera.frame_all(self._whole_scene_points(self._clip), self._aspect())
        self.update_view()

    def _whole_scene_points(self, clip: MotionClip | None) -> np.ndarray:
        """World points (M, 3) of the scene with `clip`, over the whole motion, not one frame."""
        scene = scene_from_clip(clip, self._playhead, self._storyboard, self.options)
        if clip is not None:
            scene.people = clip.joints.reshape(-1, 22, 3)
        return scene.points()

    def _aspect(self) -> float:
        return self.width() / max(1, self.height())

    def update_view(self) -> None:
        """Mark the picture stale; it is re-rendered on the next turn of the event loop."""
        self._dirty = True
        if self._warm:
            self._render_timer.start(0)
        else:
            self.update()

    # ---- output --------------------------------------------------------------------------
    def grab_png(self, path: str) -> bool:
        """Save the widget as it looks now (the 3D image and its overlay text)."""
        data = QByteArray()
        buffer = QBuffer(data)
        buffer.open(QIODevice.WriteOnly)
        if not self.grab().save(buffer, "PNG"):
            return False
        write_bytes(path, bytes(data))
        return True

    @property
    def ready(self) -> bool:
        """The warm-up has finished (or found no OpenGL): no render waits for a shader."""
        return self._warm and not self._warm_up_steps

    @property
    def rendered_size(self) -> tuple[int, int] | None:
        return None if self._image is None else (self._image.width(), self._image.height())

    def warm_up(self) -> None:
        """Build the renderer, then let it compile every shader (up to a second of software GL
        the first time, much less once Mesa's disk cache holds them) by drawing the example's
        warm-up scenes, one per turn of the event loop, so the window keeps responding. Does
        nothing once done."""
        if self._warm:
            return
        self._warm = True
        if self._ensure_renderer(self.width(), self.height()) is not None:
            self._warm_up_steps = warm_up_scenes()
            self._warm_up_step()
        self.update_view()

    def _warm_up_step(self) -> None:
        scene = self._warm_up_steps[0]
        if scene.objects and self._mesh_import.is_alive():
            # Poll: waiting on the import here would freeze the window for as long as it takes.
            QTimer.singleShot(50, self, self._warm_up_step)
            return
        self._renderer.draw(scene)  # draw only: the image on screen stays as it is
        self._warm_up_steps.pop(0)
        if self._warm_up_steps:
            QTimer.singleShot(0, self, self._warm_up_step)

    def paintEvent(self, event) -> None:
        painter = QPainter(self)
        if not self._warm:
            QTimer.singleShot(0, self, self.warm_up)  # once this first picture is on screen
        elif self._dirty:
            self._render()  # a paint that came before the render timer (a resize, grab) is current too
        if self._image is None:
            painter.fillRect(self.rect(), PLACEHOLDER)
            painter.drawText(self.rect(), Qt.AlignCenter | Qt.TextWordWrap, self._error or "3D view")
        elif self._image.size() == self.size():
            painter.drawImage(0, 0, self._image)
        else:  # rendered at MOVING_SCALE
            painter.setRenderHint(QPainter.SmoothPixmapTransform)
            painter.drawImage(self.rect(), self._image)
        if self.num_frames:
            painter.setPen(QColor(60, 60, 60))
            caption = self.rect().adjusted(8, 6, -8, -6)
            painter.drawText(caption, Qt.AlignLeft | Qt.AlignTop, f"frame {self.frame} / {self.num_frames - 1}")
            if self.notice:
                painter.setPen(QColor(NOTICE_COLOR))
                painter.drawText(caption.adjusted(0, painter.fontMetrics().lineSpacing(), 0, 0),
                                 Qt.AlignLeft | Qt.AlignTop | Qt.TextWordWrap, self.notice)
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

    def _ensure_renderer(self, width: int, height: int, scale: float = 1.0) -> SceneRenderer | None:
        """The renderer at this size, shown enlarged by 1 / scale; None (and the reason in
        _error) without OpenGL."""
        w, h = max(1, width), max(1, height)
        try:
            if self._renderer is None:
                self._renderer = SceneRenderer(w, h, self._config)
            self._renderer.resize(w, h, display_scale=1.0 / scale)
        except RenderUnavailableError as e:
            self._error, self._image = str(e), None
            return None
        return self._renderer

    def _render_if_stale(self) -> None:
        if self._dirty and self.isVisible():
            self._render()
            self.update()

    def _render(self) -> None:
        self._dirty = False
        moving = self._drag_mode is not None or self._rest_timer.isActive()
        scale = MOVING_SCALE if moving else 1.0
        w, h = max(1, round(self.width() * scale)), max(1, round(self.height() * scale))
        if self._ensure_renderer(w, h, scale) is None:
            return
        try:
            pixels = self._renderer.render(scene_from_clip(self._clip, self.frame, self._storyboard, self.options),
                                           self.camera)
        except RenderUnavailableError as e:
            self._error, self._image = str(e), None
            return
        # Wraps the renderer's buffer without a copy; it stays valid until the next render.
        # RGBX: translucent overlays leave alpha below 1 in the framebuffer; the view is opaque.
        self._image = QImage(pixels.data, w, h, 4 * w, QImage.Format_RGBX8888)
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
        dragged = self._image is not None and self._image.size() != self.size()
        self._drag_pos = self._drag_mode = None
        if dragged:
            self.update_view()  # back to full resolution

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
            self._rest_timer.start(CAMERA_REST_MS)
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
