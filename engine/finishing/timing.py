"""The keys' timing (Keypose.hold, ease_in, ease_out) given to the generated motion by retiming it.

The network animates the keys as instants. An animator also says how long a pose is held and
whether the motion slows into it and starts slowly out of it (a flat tangent on an animation
curve). Both are a map from each frame f of a person to a time s(f) of the generated motion:

- through a hold [k, k + hold] time stands still at k: the pose of the key;
- between the end of a hold (or the clip's start) at a and the next key at b, the generated
  motion from the key at k <= a to b is played in the frames a..b: s = k + (b - k) e(u),
  u = (f - a) / (b - a), with e the cubic Hermite curve from 0 to 1 whose slope is 0 at an eased
  end (speed goes to zero there) and 1 at any other;
- after the last key's hold the motion goes on from its key at its own speed (eased out if asked).

Key frames map to themselves, so the warp that follows (warp.py) makes them exact; it is given
each held key again where its hold ends (`with_hold_ends`), so that it corrects the whole hold
alike. The person is retimed alone: an object they hold follows their hands (contacts.py).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..storyboard import Keypose, Storyboard


def hermite_time(u: np.ndarray, slope_start: float, slope_end: float) -> np.ndarray:
    """e(u) on [0, 1]: e(0) = 0, e(1) = 1, e'(0) = slope_start, e'(1) = slope_end."""
    return (u ** 3 - 2 * u ** 2 + u) * slope_start + (3 * u ** 2 - 2 * u ** 3) + (u ** 3 - u ** 2) * slope_end


def held_until(keys: list[Keypose], i: int, last: int) -> int:
    """The last frame key i of a person's sorted keys is held: its hold, ended before the next key."""
    end = keys[i].frame + keys[i].hold
    if i + 1 < len(keys):
        end = min(end, keys[i + 1].frame - 1)
    return max(keys[i].frame, min(end, last))


def holds(storyboard: Storyboard, agent: str) -> list[tuple[Keypose, int]]:
    """The agent's keys in time order, each with the last frame its pose is held (held_until)."""
    keys = sorted((k for k in storyboard.keyposes if k.agent == agent), key=lambda k: k.frame)
    return [(k, held_until(keys, i, storyboard.length - 1)) for i, k in enumerate(keys)]


def source_times(keys: list[Keypose], n: int) -> np.ndarray | None:
    """(n,) times of the generated motion shown at each frame, for a person's keys sorted by frame
    (None where no key is timed: the motion as generated)."""
    if not any(k.hold or k.ease_in or k.ease_out for k in keys):
        return None
    last = n - 1
    s = np.arange(n, dtype=float)
    start, source, slope = 0, 0.0, 1.0          # where the moving span starts, from which time, how
    for i, k in enumerate(keys):
        _play(s, start, k.frame, source, k.frame, slope, 0.0 if k.ease_in else 1.0)
        start, source, slope = held_until(keys, i, last), float(k.frame), 0.0 if k.ease_out else 1.0
        s[k.frame:start + 1] = k.frame
    _play(s, start, last, source, source + (last - start), slope, 1.0)
    return np.minimum(s, last)           # after a hold the clip ends before its motion does


def _play(s: np.ndarray, a: int, b: int, source_a: float, source_b: float, slope_a: float, slope_b: float) -> None:
    """Frames a..b show the generated times source_a..source_b along e (in place)."""
    if b > a:
        u = np.linspace(0.0, 1.0, b - a + 1)
        s[a:b + 1] = source_a + (source_b - source_a) * hermite_time(u, slope_a, slope_b)


def retime_to_keys(joints: np.ndarray, storyboard: Storyboard) -> np.ndarray:
    """Joints (N, H, 22, 3), people in the storyboard's agent order, retimed to their keys' timing."""
    out = joints.copy()
    n = len(joints)
    for h, agent in enumerate(storyboard.agents):
        keys = sorted((k for k in storyboard.keyposes if k.agent == agent.id and k.frame < n), key=lambda k: k.frame)
        s = source_times(keys, n)
        if s is None:
            continue
        below = np.clip(np.floor(s).astype(int), 0, n - 2)
        w = (s - below)[:, None, None]
        out[:, h] = (1 - w) * joints[below, h] + w * joints[below + 1, h]
    return out


def with_hold_ends(storyboard: Storyboard) -> Storyboard:
    """The storyboard with each held key keyed again (untimed) on the last frame of its hold."""
    ends = [replace(k, frame=end, hold=0, ease_in=False, ease_out=False)
            for agent in storyboard.agents for k, end in holds(storyboard, agent.id) if end > k.frame]
    return replace(storyboard, keyposes=storyboard.keyposes + ends) if ends else storyboard
