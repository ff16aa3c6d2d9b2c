"""What the views draw besides the sketch and the motion: a small model that the View menu edits
and the canvas and the 3D view observe, kept in the settings between sessions."""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

from PySide6.QtCore import QObject, QSettings, Signal

from engine.render import SceneOptions

_SCENE = SceneOptions()


@dataclass(frozen=True)
class ViewOptions:
    onion: bool = True                          # the generated motion under the sketch (canvas)
    ghosts: bool = _SCENE.ghosts                # 3D: the motion's bodies at the keyframes
    target_paths: bool = _SCENE.target_paths    # 3D: the sketched paths, lifted
    generated_paths: bool = _SCENE.generated_paths  # 3D: the motion's paths of sketched joints

    def scene(self, base: SceneOptions = _SCENE) -> SceneOptions:
        """The 3D view's options with these overlays."""
        return replace(base, ghosts=self.ghosts, target_paths=self.target_paths,
                       generated_paths=self.generated_paths)


LABELS = {"onion": "Onion Skin", "ghosts": "3D Keyframe Ghosts", "target_paths": "3D Sketched Paths",
          "generated_paths": "3D Generated Paths"}


class ViewOptionsModel(QObject):
    changed = Signal(object)   # ViewOptions

    def __init__(self, settings: QSettings | None = None, parent: QObject | None = None):
        super().__init__(parent)
        self._settings = settings
        saved = {f.name: _as_bool(settings.value(f"view/{f.name}"), f.default) if settings is not None else f.default
                 for f in fields(ViewOptions)}
        self.options = ViewOptions(**saved)

    def set(self, **changes: bool) -> None:
        new = replace(self.options, **changes)
        if new == self.options:
            return
        self.options = new
        if self._settings is not None:
            for name, value in asdict(new).items():
                self._settings.setValue(f"view/{name}", value)
        self.changed.emit(new)


def _as_bool(value, default: bool) -> bool:
    """QSettings hands back what an INI file holds as text: 'true' / 'false'."""
    if value is None:
        return default
    return value if isinstance(value, bool) else str(value).lower() in ("true", "1")
