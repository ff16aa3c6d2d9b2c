"""Freehand strokes: smoothing, even resampling, partial redraw and hit testing. Pure numpy;
all points are sketch-plane metres, polylines are (L, 2) arrays."""
from __future__ import annotations

import numpy as np

from engine.geometry.polylines import resample_polyline
from engine.storyboard import MAX_POLYLINE_POINTS

SPACING = 0.04   # metres between stored stroke points: smooth enough, small files


def smooth(raw: np.ndarray, window: int = 5) -> np.ndarray:
    """Moving average of (L, 2) mouse samples (hand jitter out) over `window` points SPACING / 2
    apart along the stroke, so that over the same length of stroke however fast it was drawn (over
    5 samples, a semicircle drawn fast in 7 came out 26% flatter); the ends kept where they were."""
    raw = resample_even(np.asarray(raw, float), SPACING / 2)
    if len(raw) < window:
        return raw
    kernel = np.ones(window) / window
    padded = np.concatenate([np.repeat(raw[:1], window // 2, 0), raw, np.repeat(raw[-1:], window // 2, 0)])
    out = np.stack([np.convolve(padded[:, d], kernel, "valid") for d in range(2)], -1)
    out[0], out[-1] = raw[0], raw[-1]
    return out


def resample_even(points: np.ndarray, spacing: float = SPACING) -> np.ndarray:
    """(L, 2) -> (M, 2) points `spacing` metres apart along the polyline (M >= 2), ends kept; a
    stroke too long for that many (a minute of scribbling) takes the most a file may hold."""
    length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=-1)))
    return resample_polyline(points, min(max(2, int(np.ceil(length / spacing)) + 1), MAX_POLYLINE_POINTS))


def clean_stroke(raw: np.ndarray, spacing: float = SPACING) -> np.ndarray:
    """Raw mouse samples (L, 2) -> smoothed polyline evenly spaced in arc length."""
    return resample_even(smooth(raw), spacing)


def closest_point(polyline: np.ndarray, p) -> tuple[int, float]:
    """Index of the polyline vertex nearest to p (2,), and its distance."""
    d = np.linalg.norm(polyline - np.asarray(p, float), axis=-1)
    i = int(np.argmin(d))
    return i, float(d[i])


def splice(existing: np.ndarray, stroke: np.ndarray, snap: float) -> np.ndarray | None:
    """Redraw part of `existing` with `stroke`, or None when the stroke does not start within
    `snap` metres of it. A stroke that also ends near the polyline replaces the part between
    its two ends; one that ends away from it replaces everything after its start."""
    start, d0 = closest_point(existing, stroke[0])
    if d0 > snap:
        return None
    stroke = smooth(stroke)   # only the new part is smoothed; the rest stays as drawn
    end, d1 = closest_point(existing, stroke[-1])
    if d1 > snap:
        # Starting at the very first point redraws the head; anywhere else redraws the tail.
        if start < 2:
            return resample_even(np.concatenate([stroke[::-1], existing[start + 1:]]))
        return resample_even(np.concatenate([existing[:start], stroke]))
    if end < start:
        start, end, stroke = end, start, stroke[::-1]
    return resample_even(np.concatenate([existing[:start], stroke, existing[end + 1:]]))
