"""The viewport's orbit camera and the 4x4 matrices it produces.

Angles follow engine/camera.py: yaw about +Y (0 looks from +Z, 90 from +X), pitch above the
horizon, both in degrees. Matrices are row-major numpy (4, 4) float32 acting on column vectors;
transpose them when handing them to GL.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MIN_PITCH, MAX_PITCH = -10.0, 89.0
MIN_DISTANCE, MAX_DISTANCE = 0.3, 200.0


@dataclass
class OrbitCamera:
    yaw: float = 35.0
    pitch: float = 18.0
    distance: float = 6.0
    target: tuple[float, float, float] = (0.0, 0.9, 0.0)
    fov: float = 40.0  # vertical field of view, degrees

    def basis(self) -> np.ndarray:
        """(3, 3) rows: right, up, towards-camera unit vectors in world coordinates."""
        y, p = math.radians(self.yaw), math.radians(self.pitch)
        back = np.array([math.cos(p) * math.sin(y), math.sin(p), math.cos(p) * math.cos(y)])
        right = np.array([math.cos(y), 0.0, -math.sin(y)])
        return np.stack([right, np.cross(back, right), back])

    def eye(self) -> np.ndarray:
        return np.asarray(self.target, float) + self.distance * self.basis()[2]

    def view_matrix(self) -> np.ndarray:
        right, up, back = self.basis()
        m = np.eye(4)
        m[:3, :3] = np.stack([right, up, back])
        m[:3, 3] = -m[:3, :3] @ self.eye()
        return m.astype(np.float32)

    def projection_matrix(self, aspect: float) -> np.ndarray:
        near, far = max(0.02, self.distance * 0.02), self.distance * 20 + 50
        f = 1.0 / math.tan(math.radians(self.fov) / 2)
        m = np.zeros((4, 4))
        m[0, 0], m[1, 1] = f / aspect, f
        m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
        m[3, 2] = -1.0
        return m.astype(np.float32)

    # ---- interaction -----------------------------------------------------------------------
    def orbit(self, d_yaw: float, d_pitch: float) -> None:
        """Turn around the target by degrees; pitch stays between just below the horizon and top-down."""
        self.yaw = (self.yaw + d_yaw) % 360.0
        self.pitch = min(MAX_PITCH, max(MIN_PITCH, self.pitch + d_pitch))

    def pan(self, dx: float, dy: float) -> None:
        """Slide the target in the view plane; dx, dy are fractions of the view height."""
        height = 2 * self.distance * math.tan(math.radians(self.fov) / 2)
        right, up, _ = self.basis()
        self.target = tuple(np.asarray(self.target, float) + height * (-dx * right + dy * up))

    def zoom(self, factor: float) -> None:
        """Multiply the distance to the target (factor < 1 moves closer)."""
        self.distance = min(MAX_DISTANCE, max(MIN_DISTANCE, self.distance * factor))

    def frame_all(self, points: np.ndarray, aspect: float = 16 / 9, pad: float = 0.15,
                  margin: float = 1.05) -> None:
        """Aim at and fit world points (M, 3), keeping the angles: the target is the centre of
        their box, the distance the least at which every point, `pad` metres around it (joints
        are inside limbs) and `margin` times its offset from the target, is in view. A bounding
        sphere would leave half the picture empty."""
        pts = np.asarray(points, float).reshape(-1, 3)
        centre = (pts.min(0) + pts.max(0)) / 2
        need = self._distance_to_see(pts, centre, aspect, pad, margin)
        self.target = tuple(centre)
        tan_v = math.tan(math.radians(self.fov) / 2)
        self.distance = min(MAX_DISTANCE, max(MIN_DISTANCE, need, 0.5 / tan_v))  # at least 1 m of view height

    def sees(self, points: np.ndarray, aspect: float = 16 / 9, pad: float = 0.15) -> bool:
        """Whether every world point (M, 3), `pad` metres around it, is in view as the camera is."""
        pts = np.asarray(points, float).reshape(-1, 3)
        return self._distance_to_see(pts, np.asarray(self.target, float), aspect, pad, 1.0) <= self.distance

    def _distance_to_see(self, points: np.ndarray, target: np.ndarray, aspect: float, pad: float,
                         margin: float) -> float:
        """The least distance from `target` at which the camera, at its angles, sees every point
        (M, 3) with `pad` metres around it and `margin` times its offset from the target."""
        right, up, back = ((points - target) @ self.basis().T).T
        tan_v = math.tan(math.radians(self.fov) / 2)
        spread = np.maximum((np.abs(right) + pad) / (tan_v * aspect), (np.abs(up) + pad) / tan_v)
        return float(np.max(back + margin * spread))
