"""Which way a held object faces (its yaw about +Y, radians): fitted to the holding wrists, then
turning with its holder's chest, or with the line between two holders, each holder's grips on
their side (a holder's left hand's on their left), and eased where hands join or leave the hold
(held.py places it)."""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..geometry.rotations import norm, quat_to_matrix
from ..rig import CHEST
from ..synth.reach import heading_of, wrap_angle
from .blend import ease_frames, ease_jumps
from .contacts import ContactConfig, forward_of

MIN_APART = 0.3   # m between two holders' chests, under which the line between them turns too fast
FACING_SLACK = np.pi / 4   # rad a shared object may turn each holder's grips off the side facing them


def yaw_of(quat: np.ndarray) -> np.ndarray:
    """Heading of a pose's local +X about +Y: (..., 4) wxyz -> (...)."""
    x_axis = quat_to_matrix(quat)[..., :, 0]
    return np.arctan2(-x_axis[..., 2], x_axis[..., 0])


def fit_yaw(wrists: np.ndarray, grips: np.ndarray, held: np.ndarray,
            min_spread: float) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the heading that best turns the local grips onto the holding wrists (weighted
    upright Procrustes). Upright because a yaw-only fit stays defined with both hands on one end
    and carried boxes and tables stay level. wrists, grips (N, P, 3); held (N, P) bool.
    Returns yaw (N,) and where it is defined (N,): two or more grips spread apart."""
    w = held[..., None]
    count = np.maximum(w.sum(axis=1, keepdims=True), 1)
    p = w * (wrists - np.sum(w * wrists, axis=1, keepdims=True) / count)
    a = grips - np.sum(w * grips, axis=1, keepdims=True) / count
    # yaw_matrix turns (x, z) into (c x + s z, -s x + c z); maximise sum p . R a over the angle.
    sin = np.sum(p[..., 0] * a[..., 2] - p[..., 2] * a[..., 0], axis=1)
    cos = np.sum(p[..., 0] * a[..., 0] + p[..., 2] * a[..., 2], axis=1)
    return np.arctan2(sin, cos), np.hypot(sin, cos) > min_spread


def _grips_apart(grips: np.ndarray, held: np.ndarray, first: list[int], second: list[int]) -> np.ndarray | None:
    """The horizontal vector (3,), in the object's frame, from the grips the hands `first` hold to
    those the hands `second` hold over some frames (hands index grips (M, 2H, 3) local and held
    (M, 2H)); None where either holds nothing or their grips lie within 5 cm of each other (one
    handle shared: no side is either's)."""
    centres = []
    for hands in (first, second):
        count = held[:, hands].sum()
        if not count:
            return None
        centres.append(np.sum(grips[:, hands] * held[:, hands, None], axis=(0, 1)) / count)
    apart = (centres[1] - centres[0]) * (1.0, 0.0, 1.0)
    return apart if norm(apart) > 0.05 else None


def carried_yaw(yaw: np.ndarray, joints: np.ndarray, holding: np.ndarray, sigma: float, grips: np.ndarray,
                held: np.ndarray) -> np.ndarray:
    """A held object's heading (N,) turning with its holder's chest while one person alone holds it
    (holding (N, H) bool; joints (N, H, 22, 3)), and with the line between the first two holders'
    chests while several do, at the heading the fit gives it there for most of the frames (the
    median turn from the mean): a yaw fitted to one person's two wrists spun the object a full
    turn in ten frames as the wrists crossed, and one fitted to two carriers' wrists half a turn
    and back in fifteen (their warped hands met over a canister; walking on 10 degrees apart,
    they reached through it for its far grips, an arm 12 cm inside). Chest headings and
    positions are smoothed over `sigma` frames. On artist_check's 100 storyboards (scenes 0-49,
    seed 0): the deepest penetration 12.2 -> 7.8 cm (mean 1.44 -> 1.28 cm; within 2 cm 75 -> 72),
    pops within 5 cm 63 -> 66, grips within 3 cm 100 -> 100. Where that heading turns the grips
    of each of two holders more than FACING_SLACK away from their side (grips (N, 2H, 3) local,
    held (N, 2H), as in held.py), each holder's grips face them instead: a canister whose wrists'
    fit turned it a quarter round had a carrier reach across its top for the far grips, a forearm
    8.2 cm inside (0.5 cm so; artist_check's 3 x 100 storyboards: within 2 cm 270 -> 271, grips
    within 3 cm 295 -> 296, nothing else changed). So for one holder whose two hands hold apart:
    the left hand's grip on their left (crossed hands, a box turned half round; pops within 5 cm
    269 -> 271 of 300, grips and penetration as many)."""
    yaw = np.unwrap(yaw)
    chest = gaussian_filter1d(np.unwrap(heading_of(forward_of(joints)), axis=0), sigma, axis=0, mode="nearest")  # (N, H)
    centre = gaussian_filter1d(joints[:, :, CHEST], sigma, axis=0, mode="nearest")                # (N, H, 3)
    holders = holding @ (1 << np.arange(holding.shape[1]))                         # (N,) who holds, as bits
    runs = np.flatnonzero(np.diff(np.concatenate([[-1], holders, [-1]])))          # where the holders change
    for start, stop in zip(runs[:-1], runs[1:]):
        people = np.flatnonzero(holding[start])
        if len(people) == 1:
            along = chest[start:stop, people[0]]
        elif len(people) > 1:
            between = centre[start:stop, people[1]] - centre[start:stop, people[0]]
            if norm(between[:, [0, 2]]).min() < MIN_APART:
                continue   # too close together for the line between them to say a heading
            along = np.unwrap(heading_of(between))
        else:
            continue
        offset = yaw[start:stop] - along
        mean = np.arctan2(np.mean(np.sin(offset)), np.mean(np.cos(offset)))
        yaw[start:stop] = along + mean + np.median(wrap_angle(offset - mean))
        if len(people) > 1:   # from the first holder's grips to the second's: along the line between them
            a, b = people[:2]
            first, second, turn = [2 * a, 2 * a + 1], [2 * b, 2 * b + 1], 0.0
        else:                 # from the holder's left hand's grip to their right's: to their right
            first, second, turn = [2 * people[0]], [2 * people[0] + 1], np.pi / 2
        apart = _grips_apart(grips[start:stop], held[start:stop], first, second)
        if apart is not None:
            facing = along - turn - heading_of(apart)
            if abs(np.median(wrap_angle(yaw[start:stop] - facing))) > FACING_SLACK:
                yaw[start:stop] = facing
    return yaw


def eased_handovers(yaw: np.ndarray, held: np.ndarray, grips: np.ndarray, config: ContactConfig) -> np.ndarray:
    """A held object's fitted heading (N,) (unwrapped; held, grips as in _hold_one) with its
    jumps where a hand joins or leaves the hold eased out: the heading of two people's hands is
    not one person's chest's, and a partner letting go of a box turned it 69 degrees in a frame.
    (Its position's jumps are left: eased, the grips went out of the new holder's reach.)"""
    hands = held.reshape(len(held), -1)
    holding = hands.any(axis=1)
    changes = (np.flatnonzero(holding[1:] & holding[:-1] & np.any(hands[1:] != hands[:-1], axis=1)) + 1).tolist()
    if not changes:
        return yaw
    radius = np.max(norm(grips[..., [0, 2]]))   # how far a turn moves a grip
    return ease_jumps(yaw[:, None], changes, lambda turn: ease_frames(
        radius * turn, config.handover_pop, config.blend_frames, config.most_handover_frames))[:, 0]
