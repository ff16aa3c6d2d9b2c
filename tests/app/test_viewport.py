"""The Viewport widget under QT_QPA_PLATFORM=offscreen: it paints the scene, the mouse moves
the camera, it shows the frame it is given, its playback keys only ask, and grab_png writes a
picture. (The playback clock itself is app.playback.Playback, tested in tests/app.)"""
import os
from dataclasses import replace

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from PySide6.QtCore import QPoint, QPointF, Qt  # noqa: E402
from PySide6.QtGui import QImage, QWheelEvent  # noqa: E402
from PySide6.QtWidgets import QApplication  # noqa: E402

from app.viewport import Viewport  # noqa: E402
from engine.render import RenderUnavailableError, shared_context  # noqa: E402
from engine.render.example import carry_clip, carry_storyboard  # noqa: E402


def new_viewport(qtbot) -> Viewport:
    """A 320x240 viewport holding the carry example's clip, not yet shown."""
    try:
        shared_context()
    except RenderUnavailableError as e:
        pytest.skip(str(e))
    view = Viewport()
    qtbot.addWidget(view)
    view.resize(320, 240)
    view.set_clip(carry_clip(12))
    return view


@pytest.fixture
def viewport(qtbot):
    view = new_viewport(qtbot)
    view.set_storyboard(carry_storyboard(carry_clip(12)))
    view.show()
    qtbot.waitExposed(view)
    qtbot.waitUntil(lambda: view.ready)  # the first paint showed a placeholder, then it warmed up
    return view


def grab_rgb(view) -> np.ndarray:
    image = view.grab().toImage().convertToFormat(QImage.Format_RGB888)
    w, h = image.width(), image.height()
    return np.frombuffer(image.constBits(), np.uint8).reshape(h, image.bytesPerLine())[:, :3 * w].reshape(h, w, 3)


def test_paints_the_people(viewport):
    pixels = grab_rgb(viewport).astype(int)
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    assert ((r - g > 90) & (g - b > 10)).sum() > 100   # agent 0
    assert (b - r > 60).sum() > 100                   # agent 1


def test_left_drag_orbits_and_wheel_zooms(viewport, qtbot):
    yaw, distance = viewport.camera.yaw, viewport.camera.distance
    qtbot.mousePress(viewport, Qt.LeftButton, pos=QPoint(100, 120))
    qtbot.mouseMove(viewport, QPoint(160, 120))
    qtbot.mouseRelease(viewport, Qt.LeftButton, pos=QPoint(160, 120))
    assert viewport.camera.yaw != pytest.approx(yaw)
    target = viewport.camera.target
    qtbot.mousePress(viewport, Qt.LeftButton, Qt.ShiftModifier, QPoint(100, 120))
    qtbot.mouseMove(viewport, QPoint(130, 140))
    qtbot.mouseRelease(viewport, Qt.LeftButton, Qt.ShiftModifier, QPoint(130, 140))
    assert not np.allclose(viewport.camera.target, target)
    pos = QPointF(160, 120)
    wheel = QWheelEvent(pos, viewport.mapToGlobal(pos), QPoint(), QPoint(0, 240), Qt.NoButton,
                        Qt.NoModifier, Qt.NoScrollPhase, False)
    QApplication.sendEvent(viewport, wheel)
    assert viewport.camera.distance < distance
    before = grab_rgb(viewport).copy()
    qtbot.keyClick(viewport, Qt.Key_F)
    assert not np.array_equal(grab_rgb(viewport), before)


def test_shows_the_frame_it_is_given(viewport):
    first = grab_rgb(viewport).copy()
    viewport.set_frame(viewport.num_frames - 1)
    assert viewport.frame == viewport.num_frames - 1
    assert not np.array_equal(grab_rgb(viewport), first)   # the people moved
    viewport.set_frame(500)   # past a short clip: its last frame shows, the playhead is kept
    assert viewport.frame == viewport.num_frames - 1
    viewport.set_clip(carry_clip(600))
    viewport.set_frame(500)
    assert viewport.frame == 500


def test_playback_keys_request_and_do_not_move_the_frame(viewport, qtbot):
    toggles, steps = [], []
    viewport.playToggleRequested.connect(lambda: toggles.append(True))
    viewport.stepRequested.connect(steps.append)
    viewport.set_frame(3)
    viewport.setFocus()
    for key in (Qt.Key_Space, Qt.Key_Right, Qt.Key_Left):
        qtbot.keyClick(viewport, key)
    assert toggles == [True] and steps == [1, -1]
    assert viewport.frame == 3


def test_preview_keeps_the_frame_and_camera(viewport):
    viewport.set_frame(5)
    viewport.camera.orbit(30, 0)
    yaw = viewport.camera.yaw
    viewport.set_preview(carry_clip(12))
    assert viewport.frame == 5 and viewport.camera.yaw == yaw


def test_grab_png_writes_a_picture(viewport, tmp_path):
    path = tmp_path / "view.png"
    assert viewport.grab_png(path)
    image = QImage(str(path))
    assert (image.width(), image.height()) == (320, 240)


def test_first_paint_is_a_placeholder_then_the_scene(qtbot):
    view = new_viewport(qtbot)
    view.show()
    first = grab_rgb(view)   # painted before the event loop could warm anything up
    assert not view.ready and view.rendered_size is None
    assert (np.abs(first.astype(int) - [0xdf, 0xe3, 0xe8]).sum(-1) < 8).mean() > 0.9
    qtbot.waitUntil(lambda: view.ready)
    qtbot.waitUntil(lambda: view.rendered_size == (320, 240))
    r, g, b = (grab_rgb(view)[..., i].astype(int) for i in range(3))
    assert ((r - g > 90) & (g - b > 10)).sum() > 100


def test_a_moving_camera_renders_smaller_and_full_size_once_it_rests(viewport, qtbot):
    qtbot.waitUntil(lambda: viewport.rendered_size == (320, 240))
    qtbot.mousePress(viewport, Qt.LeftButton, pos=QPoint(100, 120))
    qtbot.mouseMove(viewport, QPoint(140, 120))
    qtbot.waitUntil(lambda: viewport.rendered_size == (160, 120))
    dragging = grab_rgb(viewport)
    assert dragging.shape == (240, 320, 3)   # scaled up to the widget
    r, g, b = (dragging[..., i].astype(int) for i in range(3))
    assert ((r - g > 90) & (g - b > 10)).sum() > 100 and (b - r > 60).sum() > 100
    qtbot.mouseRelease(viewport, Qt.LeftButton, pos=QPoint(140, 120))
    qtbot.waitUntil(lambda: viewport.rendered_size == (320, 240))
    wheel = QWheelEvent(QPointF(160, 120), viewport.mapToGlobal(QPointF(160, 120)), QPoint(), QPoint(0, 120),
                        Qt.NoButton, Qt.NoModifier, Qt.NoScrollPhase, False)
    QApplication.sendEvent(viewport, wheel)
    qtbot.waitUntil(lambda: viewport.rendered_size == (160, 120))
    qtbot.waitUntil(lambda: viewport.rendered_size == (320, 240))


def test_a_new_clip_keeps_the_camera_while_it_stays_in_view(viewport):
    """Framed anew for every clip, the view moved with each live preview of a drag and lost the
    artist's pan and zoom; a clip that leaves a view the last one was all in is framed."""
    viewport.camera.zoom(1.3)      # the artist steps back a little, and pans
    viewport.camera.pan(0.02, 0.0)
    kept = (viewport.camera.target, viewport.camera.distance)
    clip = carry_clip(12)
    viewport.set_clip(clip)
    assert (viewport.camera.target, viewport.camera.distance) == kept and viewport.frame == 0
    away = replace(clip, joints=clip.joints + np.array([8.0, 0.0, 0.0], np.float32))
    viewport.set_clip(away)
    assert viewport.camera.sees(away.joints.reshape(-1, 3), viewport.width() / viewport.height())
    assert viewport.camera.target != kept[0]
    viewport.camera.zoom(0.3)                    # closer in than the motion fits: left so
    kept = (viewport.camera.target, viewport.camera.distance)
    viewport.set_clip(replace(away, joints=away.joints + np.array([0.2, 0.0, 0.0], np.float32)))
    assert (viewport.camera.target, viewport.camera.distance) == kept
