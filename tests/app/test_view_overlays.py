"""View menu: the 3D overlays (keyframe ghosts, sketched and generated paths) can be hidden, so
the motion itself can be judged; the picture changes accordingly."""
import numpy as np
from PySide6.QtGui import QImage

from .fakes import sample_storyboard, walking_clip


def grab_rgb(widget) -> np.ndarray:
    image = widget.grab().toImage().convertToFormat(QImage.Format_RGB888)
    buffer = np.frombuffer(image.constBits(), np.uint8, image.sizeInBytes())
    return buffer.reshape(image.height(), image.bytesPerLine())[:, :image.width() * 3].astype(int)


def test_overlay_toggles_reach_the_viewport(qtbot, window):
    sb = sample_storyboard()
    window.doc.replace_storyboard(sb, None)
    window.doc.set_result([walking_clip(sb.length, sb.fps)], None)
    view = window.viewport
    view.resize(480, 320)
    qtbot.waitUntil(lambda: view.ready)
    with_overlays = grab_rgb(view)
    for name, action in ((n, a) for n, a in window.view_actions.items() if n != "onion"):
        assert action.isChecked() and getattr(view.options, name)
        action.trigger()
        assert not getattr(view.options, name)
    without = grab_rgb(view)
    assert np.abs(with_overlays - without).sum(-1).astype(bool).mean() > 0.001  # ghosts and paths gone
    window.view_actions["ghosts"].trigger()
    assert view.options.ghosts and not view.options.target_paths
