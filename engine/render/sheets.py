"""Pictures of a whole clip for people who cannot run the viewport: a contact sheet (a grid of
frames, each labelled with its frame number) and an animated GIF. Used by `sketch2colab demo`.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ..atomic import write_bytes
from ..clip import MotionClip
from ..storyboard import Storyboard
from .camera import OrbitCamera
from .renderer import RenderConfig, SceneRenderer
from .scene import SceneOptions, scene_from_clip


def clip_camera(clip: MotionClip, storyboard: Storyboard | None, aspect: float) -> OrbitCamera:
    """One camera for every frame: framed on the whole clip (all frames, paths, ghosts) and, for
    two or more people, looking across the line between the first two (first on the left), so
    that neither hides the other or what passes between them."""
    everything = scene_from_clip(clip, 0, storyboard)
    everything.people = clip.joints.reshape(-1, 22, 3)
    camera = OrbitCamera()
    if clip.joints.shape[1] >= 2:
        apart = (clip.joints[:, 1, 0] - clip.joints[:, 0, 0])[:, [0, 2]]       # (N, 2) horizontal
        apart = apart / np.maximum(np.linalg.norm(apart, axis=-1, keepdims=True), 1e-9)
        x, z = apart.mean(axis=0)
        if np.hypot(x, z) > 0.1:   # people that swap sides have no line to look across
            camera.yaw = float(np.degrees(np.arctan2(-z, x)))                 # camera right = first -> second
    camera.frame_all(everything.points(), aspect)
    return camera


def render_frames(clip: MotionClip, frames: list[int], size: tuple[int, int] = (480, 320),
                  storyboard: Storyboard | None = None, options: SceneOptions | None = None,
                  config: RenderConfig | None = None) -> list[np.ndarray]:
    """RGB images (H, W, 3) uint8 of the given frames from one fixed camera."""
    renderer = SceneRenderer(*size, config)
    try:
        camera = clip_camera(clip, storyboard, size[0] / size[1])
        return [renderer.render(scene_from_clip(clip, f, storyboard, options), camera)[..., :3].copy()
                for f in frames]
    finally:
        renderer.release()


def write_contact_sheet(clip: MotionClip, path: str | Path, count: int = 12, columns: int = 4,
                        tile: tuple[int, int] = (320, 240), storyboard: Storyboard | None = None) -> list[int]:
    """Save a PNG grid of `count` evenly spaced frames (fewer if the clip is shorter).
    Returns the frame numbers shown, in reading order."""
    frames = sorted(set(np.linspace(0, clip.num_frames - 1, min(count, clip.num_frames)).round().astype(int).tolist()))
    images = render_frames(clip, frames, tile, storyboard, SceneOptions(ghosts=False))
    rows = -(-len(frames) // columns)
    sheet = Image.new("RGB", (columns * tile[0], rows * tile[1]), "white")
    for i, (frame, image) in enumerate(zip(frames, images)):
        x, y = (i % columns) * tile[0], (i // columns) * tile[1]
        sheet.paste(Image.fromarray(image), (x, y))
        draw = ImageDraw.Draw(sheet)
        label = f"{frame}"
        box = draw.textbbox((x + 8, y + 6), label)
        draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(40, 40, 40))
        draw.text((x + 8, y + 6), label, fill=(255, 255, 255))
    write_bytes(path, _encoded(sheet, format="PNG"))
    return frames


def write_gif(clip: MotionClip, path: str | Path, size: tuple[int, int] = (480, 320), stride: int = 1,
              storyboard: Storyboard | None = None) -> int:
    """Save an animated GIF of every `stride`-th frame at the clip's speed, looping.
    Returns the number of frames written. Pillow folds identical consecutive frames into one
    longer frame, so a clip that stands still has fewer GIF frames than it has frames."""
    frames = list(range(0, clip.num_frames, max(1, stride)))
    images = [Image.fromarray(a) for a in render_frames(clip, frames, size, storyboard, SceneOptions(ghosts=False))]
    duration = int(round(1000 * max(1, stride) / clip.fps))
    write_bytes(path, _encoded(images[0], format="GIF", save_all=True, append_images=images[1:], duration=duration,
                                loop=0))
    return len(images)


def _encoded(image: Image.Image, **options) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, **options)
    return buffer.getvalue()
