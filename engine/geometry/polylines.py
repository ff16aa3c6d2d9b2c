"""Polylines (L, D), L >= 1: nearest points, distances and arc-length resampling."""
from __future__ import annotations

import numpy as np


def closest_on_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """The nearest point of a polyline (L, D) to each of points (P, D) -> (P, D)."""
    poly = np.asarray(polyline, float)
    if len(poly) == 1:
        poly = np.concatenate([poly, poly])
    a, seg = poly[:-1], np.diff(poly, axis=0)                               # (S, D)
    rel = np.asarray(points, float)[:, None] - a[None]                      # (P, S, D)
    t = np.clip(np.sum(rel * seg, axis=-1) / np.maximum(np.sum(seg * seg, axis=-1), 1e-24), 0.0, 1.0)
    nearest = a[None] + t[..., None] * seg                                  # (P, S, D)
    best = np.argmin(np.linalg.norm(rel - t[..., None] * seg, axis=-1), axis=1)
    return nearest[np.arange(len(nearest)), best]


def point_polyline_distance(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Exact distance of points (P, D) to a polyline (L, D) -> (P,)."""
    return np.linalg.norm(np.asarray(points, float) - closest_on_polyline(points, polyline), axis=-1)


def resample_polyline(points: np.ndarray, count: int) -> np.ndarray:
    """(L, D) polyline -> (count, D) points evenly spaced in arc length, ends kept."""
    points = np.asarray(points, float)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if count == 1:
        return points[:1].copy()
    if s[-1] < 1e-12:  # a stroke that never moves: every sample is its first point
        return np.repeat(points[:1], count, axis=0)
    target = np.linspace(0.0, s[-1], count)
    return np.stack([np.interp(target, s, points[:, d]) for d in range(points.shape[1])], axis=-1)
