"""The 3D scene renderer shared by the app's viewport and the headless CLI (no Qt here).

    from engine.render import SceneRenderer, OrbitCamera, scene_from_clip
    renderer = SceneRenderer(1280, 720)
    image = renderer.render(scene_from_clip(clip, frame, storyboard), camera)  # (720, 1280, 4) uint8

It draws through the process's one standalone EGL moderngl context (context.py) with the GLSL
in the repository's shaders/ directory. sheets.py writes contact sheets and GIFs of a clip;
`python -m engine.render.benchmark` times the viewport's frames.
"""
from .camera import OrbitCamera
from .context import RenderUnavailableError, is_software, shared_context
from .renderer import RenderConfig, SceneRenderer
from .scene import PlacedObject, Polyline, SceneOptions, SceneState, lift_storyboard_paths, scene_from_clip

__all__ = ["OrbitCamera", "PlacedObject", "Polyline", "RenderConfig", "RenderUnavailableError",
           "SceneOptions", "SceneRenderer", "SceneState", "is_software", "lift_storyboard_paths",
           "scene_from_clip", "shared_context"]
