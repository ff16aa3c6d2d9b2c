"""A held object moved onto what the artist drew of it: its base onto its paths, its centre onto
its outlines (held.py fits it to the holding hands first; contacts.py then puts the hands on its
grips), never further than its holders reach. World metres, Y up; the sketch plane is the
storyboard camera's."""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, minimum_filter1d

from ..camera import StoryboardCamera
from ..geometry.polylines import closest_on_polyline
from ..geometry.rotations import norm
from ..objects import ObjectSpec
from ..skeleton import SHOULDERS
from ..synth.reach import yaw_matrix
from .contacts import ContactConfig, arm_lengths
from .keys import spread


def onto_drawing(pos: np.ndarray, yaw: np.ndarray, joints: np.ndarray, grips: np.ndarray, held: np.ndarray,
                 spans: list[tuple[int, int]], drawn: dict[int, np.ndarray], paths: list[tuple[int, int, np.ndarray]],
                 spec: ObjectSpec, camera: StoryboardCamera, config: ContactConfig) -> np.ndarray:
    """A held object's fitted origin (N, 3), turned by yaw (N,), moved in the sketch plane onto
    what the artist drew of it while it is held: its base onto its paths (`paths`: (start, end,
    points (L, 2)) each; the nearest point, smoothed over path_smoothing frames: a path has no
    timing), then its centre onto the silhouettes drawn at key frames of its holds (`drawn`:
    frame -> the outline's centre (2,)), each hold's moves spread between its keys and faded over
    drawn_falloff frames beyond them. Fitted to the wrists alone, a box's base was 6.0 cm off its
    path on average (17 cm for one frame in twenty) and its centre 5.4 cm off its outlines, while
    an artist's strokes are within 2 cm of where it is (artist_check's 3 x 100 storyboards); moved
    so, 4.5 and 4.3 cm, as far as no held grip goes beyond its holder's reach, or further beyond
    it than it was (_reachable_share): where the holders stand off the drawing, the arms cannot
    close the gap (unbounded, 3.4 cm, but 2 more holds lost their grips). joints (N, H, 22, 3), grips
    (N, 2H, 3) local, held (N, 2H) as in held._hold_one; spans: the inclusive frame spans of its holds."""
    right, up, _ = camera.basis()

    def in_plane(miss: np.ndarray) -> np.ndarray:   # sketch-plane moves (..., 2) -> world (..., 3)
        return miss[..., :1] * right + miss[..., 1:] * up

    holding = held.any(axis=1)
    move = np.zeros_like(pos)
    for start, end, points in paths:
        frames = start + np.flatnonzero(holding[start:end + 1])
        seen = camera.project(pos[frames])
        move[frames] = in_plane(closest_on_polyline(seen, points) - seen)
    move = gaussian_filter1d(move, config.path_smoothing, axis=0, mode="nearest")
    centre = np.array([0.0, spec.size[1] / 2, 0.0])
    for start, end in spans:
        keys = sorted(f for f in drawn if start <= f <= end)
        if keys:
            miss = np.stack([drawn[f] - camera.project(pos[f] + move[f] + centre) for f in keys])   # (K, 2)
            move[start:end + 1] += spread(end - start + 1, [f - start for f in keys], in_plane(miss),
                                          config.drawn_falloff)
    share = _reachable_share(pos, yaw, move, joints, grips, held, config)
    # Eased: the share a frame allows held over the frames around it, then smoothed (never a jolt).
    window = 2 * config.blend_frames + 1
    share = gaussian_filter1d(minimum_filter1d(share, window, mode="nearest"), config.blend_frames / 2, mode="nearest")
    return pos + share[:, None] * move


def _reachable_share(pos: np.ndarray, yaw: np.ndarray, move: np.ndarray, joints: np.ndarray, grips: np.ndarray,
                     held: np.ndarray, config: ContactConfig) -> np.ndarray:
    """The largest share (N,) in [0, 1] of a move (N, 3) of the object at pos (N, 3), turned by yaw
    (N,), after which no held grip lies further from its holder's shoulder than `reach` of the
    arm, or than it lay before where it lay further (a quadratic in the share per grip)."""
    n, h = joints.shape[:2]
    shoulders = joints[:, :, list(SHOULDERS)].reshape(n, 2 * h, 3)
    reach = config.reach * arm_lengths(joints).reshape(n, 2 * h)
    away = pos[:, None] + np.einsum("nij,nkj->nki", yaw_matrix(yaw), grips) - shoulders   # (N, 2H, 3)
    limit = np.maximum(reach, norm(away))
    along, length = np.einsum("nkj,nj->nk", away, move), np.sum(move * move, axis=-1)[:, None]
    # |away + s move|^2 <= limit^2: s^2 |move|^2 + 2 s along + |away|^2 - limit^2 <= 0, true at s = 0
    root = (-along + np.sqrt(np.maximum(along ** 2 - length * (np.sum(away * away, -1) - limit ** 2), 0.0)))
    share = np.where(held & (length > 1e-12), np.clip(root / np.maximum(length, 1e-12), 0.0, 1.0), 1.0)
    return share.min(axis=1)
