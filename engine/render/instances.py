"""Instanced drawing: a unit mesh on the GPU, and growable per-instance buffers that draw it once
per row (capsules, spheres, path ribbons)."""
from __future__ import annotations

import moderngl
import numpy as np


class UnitMesh:
    """An indexed mesh on the GPU that instance streams share: (vertices, indices) from meshes.py."""

    def __init__(self, ctx: moderngl.Context, arrays: tuple[np.ndarray, np.ndarray], attribute: str):
        vertices, indices = arrays
        self.vertices, self.indices = ctx.buffer(vertices.tobytes()), ctx.buffer(indices.tobytes())
        self.layout = (self.vertices, f"{vertices.shape[1]}f", attribute)

    def release(self) -> None:
        self.vertices.release()
        self.indices.release()


class InstanceStream:
    """A growable per-instance buffer and, per program that draws it, a vertex array that pairs
    it with a shared unit mesh."""

    def __init__(self, ctx: moderngl.Context, mesh: UnitMesh, programs: list[moderngl.Program],
                 instance_format: str, instance_attrs: tuple):
        self.ctx, self.mesh, self.programs = ctx, mesh, programs
        self.instance_layout = (instance_format + "/i", *instance_attrs)
        self.buffer, self.vaos, self.count = None, [], 0

    def upload(self, rows: np.ndarray) -> None:
        data = np.ascontiguousarray(rows, np.float32)
        self.count = len(data)
        if self.count == 0:
            return
        if self.buffer is None or self.buffer.size < data.nbytes:
            self.release()
            self.buffer = self.ctx.buffer(reserve=max(data.nbytes * 2, 1024), dynamic=True)
            # skip_errors: shadow programs do not read the colour attribute.
            self.vaos = [self.ctx.vertex_array(p, [self.mesh.layout, (self.buffer, *self.instance_layout)],
                                               index_buffer=self.mesh.indices, index_element_size=4,
                                               skip_errors=True)
                         for p in self.programs]
        self.buffer.write(data)

    def draw(self, program_index: int = 0) -> None:
        if self.count:
            self.vaos[program_index].render(instances=self.count)

    def release(self) -> None:
        for vao in self.vaos:
            vao.release()
        if self.buffer is not None:
            self.buffer.release()
        self.buffer, self.vaos = None, []
