"""The one OpenGL context of the process, and shader loading.

DESIGN section 5: a single moderngl context per process, created standalone on EGL (Mesa
llvmpipe where there is no GPU). It is created on first use and then shared by every renderer;
use it only from the thread that created it (the GUI thread in the app).
Shaders live in the repository's top-level `shaders/` directory as NAME.vert / NAME.frag; a
line `#include "FILE"` pastes shaders/FILE in its place (GLSL has no includes of its own).
"""
from __future__ import annotations

import re
from pathlib import Path

import moderngl

SHADER_DIR = Path(__file__).resolve().parents[2] / "shaders"

_shared: moderngl.Context | None = None


class RenderUnavailableError(RuntimeError):
    """No OpenGL 3.3 context could be created (EGL or Mesa missing) or shaders are missing."""


def shared_context() -> moderngl.Context:
    """The process-wide standalone EGL context, created on the first call."""
    global _shared
    if _shared is None:
        try:
            _shared = moderngl.create_context(standalone=True, backend="egl", require=330)
        except Exception as e:  # moderngl raises plain Exceptions for loader and EGL failures
            raise RenderUnavailableError(
                f"cannot create an EGL OpenGL 3.3 context ({e}). On Debian install libegl1, "
                "libgl1-mesa-dri and libegl-mesa0.") from None
    return _shared


def is_software(ctx: moderngl.Context) -> bool:
    """Whether the context rasterizes on the CPU (Mesa llvmpipe or softpipe): drawing then takes
    the cores that generation would otherwise use."""
    renderer = str(ctx.info.get("GL_RENDERER", "")).lower()
    return any(name in renderer for name in ("llvmpipe", "softpipe", "swrast", "software"))


INCLUDE = re.compile(r'^#include "([^"]+)"[ \t]*$', re.MULTILINE)


def shader_source(name: str) -> str:
    """The text of shaders/NAME with its includes expanded."""
    path = SHADER_DIR / name
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        raise RenderUnavailableError(f"shader {name} not found in {SHADER_DIR}") from None
    return INCLUDE.sub(lambda m: shader_source(m.group(1)), text)


def load_program(ctx: moderngl.Context, vertex: str, fragment: str) -> moderngl.Program:
    """Compile shaders/VERTEX.vert with shaders/FRAGMENT.frag."""
    return ctx.program(vertex_shader=shader_source(vertex + ".vert"),
                       fragment_shader=shader_source(fragment + ".frag"))
