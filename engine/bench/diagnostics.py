"""Series behind the diagnostic plots, computed from what the sampler streams.

- Flow curvature over solver time: the effective velocity of step k is
  v_k = (z_k - z_{k-1}) / (t_k - t_{k-1}) from consecutive StepEvent latents; curvature at t_k
  is RMS(v_k - v_{k-1}) (0 on a straight path; the first step has no predecessor, as the
  starting noise is not streamed).
- Energy-flow alignment over solver time: the sampler does not stream its guidance gradients, so
  this recomputes one: at step k the clean estimate z0_k = z_k - t_k v_k (straight-line
  extrapolation) is decoded and the storyboard's total energy (engine.sampling.energies, all
  terms, without the CTMC gating and the lifted 3D proxies the sampler also uses) is
  differentiated w.r.t. z0_k by autograd through the decoder; alignment is
  cos(z_{k+1} - z_k, -grad), 1 when the step goes straight downhill in energy.
- Contact-timing reliability: predicted per-hand contact probability (clip.contact) binned in
  tenths against the frequency of the synthesizer's labels in each bin.
- Stroke-nudge stability: the same seed on the storyboard and on a copy whose first trajectory
  stroke has its middle point moved a few millimetres; how far the joints of the two results
  are apart. An artist who nudges a stroke expects the motion to move a little, not a new take.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from ..clip import MotionClip
from ..storyboard import Storyboard
from .runner import SampleResult

Trace = list[tuple[float, np.ndarray, dict[str, float]]]


def step_velocities(trace: Trace) -> list[tuple[float, np.ndarray]]:
    """(t_k, v_k) for k >= 1, v_k shaped like the latent."""
    return [(t1, (z1 - z0) / (t1 - t0)) for (t0, z0, _), (t1, z1, _) in zip(trace, trace[1:]) if t1 != t0]


def flow_curvature(trace: Trace) -> list[tuple[float, float]]:
    """(t_k, RMS(v_k - v_{k-1})) along the solver."""
    v = step_velocities(trace)
    return [(t, float(np.sqrt(np.mean((b - a) ** 2)))) for (_, a), (t, b) in zip(v, v[1:])]


def energy_gradient(bundle, storyboard: Storyboard, z0: np.ndarray, t: float) -> np.ndarray:
    """d E_total(decode(z0)) / d z0 for a latent (K, T, V, d) of this storyboard's scene."""
    from ..sampling.energies import EnergyContext, total_energy
    z = torch.as_tensor(z0, dtype=torch.float32).requires_grad_(True)
    with torch.enable_grad():
        motion = bundle.vqvae.decode(z)
        n, h, o = motion["joints"].shape[1], len(storyboard.agents), len(storyboard.objects)
        view = {"joints": motion["joints"][:, :, :h], "rot6d": motion["rot6d"][:, :, :h],
                "obj_pose": motion["obj_pose"][:, :, :o], "obj_anchors": motion["obj_anchors"][:, :, :o]}
        ctx = EnergyContext.from_storyboard(replace(storyboard, length=n), batch=z.shape[0])
        total, _ = total_energy(view, ctx, t)
        return torch.autograd.grad(total.sum(), z)[0].numpy()


def energy_alignment(bundle, storyboard: Storyboard, trace: Trace) -> list[tuple[float, float]]:
    """(t_k, cos(step k -> k+1, -grad E at the clean estimate of step k)) along the solver."""
    v = dict(step_velocities(trace))
    out = []
    for (t, z, _), (_, z_next, _) in zip(trace, trace[1:]):
        if t not in v:
            continue
        grad = energy_gradient(bundle, storyboard, z - t * v[t], t).ravel()
        step = (z_next - z).ravel()
        denom = np.linalg.norm(grad) * np.linalg.norm(step)
        if denom > 0:
            out.append((t, float(-grad @ step / denom)))
    return out


def mean_series(series: list[list[tuple[float, float]]]) -> list[tuple[float, float]]:
    """Average several (t, value) series over the storyboards, matched by t."""
    by_t: dict[float, list[float]] = {}
    for s in series:
        for t, value in s:
            by_t.setdefault(round(t, 6), []).append(value)
    return [(t, float(np.mean(v))) for t, v in sorted(by_t.items(), reverse=True)]


def reliability(samples: list[SampleResult], references, bins: int = 10) -> dict[str, list[float]]:
    """Per-bin mean predicted contact probability, label frequency and count, pooled over samples
    that have labels. references: item id -> held-out MotionClip."""
    prob, label = [], []
    for s in samples:
        ref = references[s.item]
        if ref.contact is not None and s.clip.contact is not None:
            prob.append(np.clip(s.clip.contact, 0, 1).ravel())
            label.append((ref.contact > 0.5).ravel())
    if not prob:
        return {"confidence": [], "frequency": [], "count": []}
    p, y = np.concatenate(prob), np.concatenate(label)
    which = np.minimum((p * bins).astype(int), bins - 1)
    count = np.bincount(which, minlength=bins)
    keep = count > 0
    return {"confidence": (np.bincount(which, p, bins)[keep] / count[keep]).tolist(),
            "frequency": (np.bincount(which, y, bins)[keep] / count[keep]).tolist(),
            "count": count[keep].tolist()}


def nudged(storyboard: Storyboard, metres: float) -> Storyboard | None:
    """A copy with the middle point of the first trajectory stroke moved `metres` along the
    sketch plane's x; None when the storyboard has no trajectory."""
    if not storyboard.trajectories:
        return None
    first = storyboard.trajectories[0]
    points = first.points.copy()
    points[len(points) // 2, 0] += metres
    return replace(storyboard, trajectories=[replace(first, points=points), *storyboard.trajectories[1:]])


def motion_change(a: MotionClip, b: MotionClip) -> tuple[float, float]:
    """Mean and largest joint displacement (m) between two clips of one storyboard."""
    distance = np.linalg.norm(a.joints - b.joints, axis=-1)
    return float(distance.mean()), float(distance.max())
