"""The storyboard camera: an orthographic view of the world, as in Sketch2Anim.

Sketch-plane coordinates (u, v) are in metres: u to the right, v up on the page. The camera
sits at `azimuth_deg` about +Y (0 looks from +Z, 90 from +X) and `elevation_deg` above the
horizon, looking at `target`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np


@dataclass
class StoryboardCamera:
    elevation_deg: float = 20.0
    azimuth_deg: float = 35.0
    target: tuple[float, float, float] = (0.0, 0.9, 0.0)

    def basis(self) -> np.ndarray:
        """(3, 3) rows: right, up, towards-camera unit vectors in world coordinates."""
        return _basis(float(self.elevation_deg), float(self.azimuth_deg)).copy()

    def project(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> sketch-plane points (..., 2)."""
        return (np.asarray(points) - np.asarray(self.target)) @ self.basis()[:2].T

    def depth(self, points: np.ndarray) -> np.ndarray:
        """Distance in front of the image plane (larger = farther away). (..., 3) -> (...)."""
        return -(np.asarray(points) - np.asarray(self.target)) @ self.basis()[2]

    def unproject_to_height(self, uv: np.ndarray, height: float | np.ndarray = 0.0) -> np.ndarray:
        """Sketch points (..., 2) -> world points (..., 3) on the plane y = height (a scalar or (...)).

        Undefined for a camera looking exactly along the horizon (elevation 0).
        """
        right, up, back = self.basis()
        origin = np.asarray(self.target) + uv[..., :1] * right + uv[..., 1:2] * up
        s = (height - origin[..., 1]) / -back[1]
        return origin - s[..., None] * back

    def to_dict(self) -> dict:
        return {"elevation_deg": self.elevation_deg, "azimuth_deg": self.azimuth_deg,
                "target": list(self.target)}

    @classmethod
    def from_dict(cls, d: dict) -> "StoryboardCamera":
        return cls(float(d["elevation_deg"]), float(d["azimuth_deg"]),
                   tuple(float(x) for x in d["target"]))


@lru_cache(maxsize=64)
def _basis(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """StoryboardCamera.basis, kept per view: the finishing asks for it some thirty times a clip."""
    el, az = np.deg2rad(elevation_deg), np.deg2rad(azimuth_deg)
    right = np.array([np.cos(az), 0.0, -np.sin(az)])
    up = np.array([-np.sin(el) * np.sin(az), np.cos(el), -np.sin(el) * np.cos(az)])
    back = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    return np.stack([right, up, back])
