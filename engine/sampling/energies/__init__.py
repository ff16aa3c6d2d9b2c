"""Differentiable guidance energies on decoded motion (paper section 3.3), and their schedule.

Every energy is `(motion, ctx, occupancy) -> (B,)` (see context.py for the shapes). Each value is a
mean over that energy's active constraints (so that doubling the constraints does not change it),
0 when none is active, never NaN, and its gradient is finite everywhere (norms are taken with a
small epsilon, soft gates carry no gradient). Units: metres (world and sketch plane), seconds for
speeds; squared errors unless stated.

    context.py   EnergyConfig, EnergyContext (built once per storyboard) and its cached constants
    geometry.py  torch geometry: camera, rotations, signed distances, body spheres, soft polylines
    terms.py     the sketch terms: keyframe, trajectory, object, contact, hand_contact, spacing
    physics.py   foot_skate, ground, smoothness, penetration

`total_energy` (here) sums the enabled terms with base weights times a schedule over solver time
t in [0, 1] (t = 1 noise, t = 0 data): keyframe-like terms early, interaction mid, physics late.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import torch
from torch import Tensor

from ...geometry.rotations_torch import quat_to_matrix, safe_norm, world_to_local
from .context import EnergyConfig, EnergyContext
from .geometry import body_points, object_sdf, project, soft_polyline_sq_distance
from .physics import foot_skate_energy, ground_energy, penetration_energy, smoothness_energy
from .terms import (contact_energy, hand_contact_energy, keyframe_energy, object_energy, spacing_energy,
                    trajectory_energy)

__all__ = ["ENERGIES", "STAGE", "EnergyConfig", "EnergyContext", "EnergySchedule", "EnergyWeights", "total_energy",
           "body_points", "object_sdf", "project", "quat_to_matrix", "safe_norm", "soft_polyline_sq_distance",
           "world_to_local"]

ENERGIES = {
    "keyframe": keyframe_energy, "trajectory": trajectory_energy, "object": object_energy,
    "contact": contact_energy, "hand_contact": hand_contact_energy, "spacing": spacing_energy,
    "penetration": penetration_energy,
    "foot_skate": foot_skate_energy, "ground": ground_energy, "smoothness": smoothness_energy,
}
# Which schedule bump each energy follows.
STAGE = {"keyframe": "early", "trajectory": "early", "object": "early",
         "contact": "mid", "hand_contact": "mid", "spacing": "mid", "penetration": "mid",
         "foot_skate": "late", "ground": "late", "smoothness": "late"}


# ---- schedule and total -----------------------------------------------------------------------

@dataclass
class EnergySchedule:
    """Smooth bumps over solver time t (1 = noise, 0 = data): a stage's factor is
    floor + (1 - floor) exp(-(t - centre)^2 / 2 width^2), so 1 at its centre and never off.
    Keyframes peak early (near noise, when the global layout forms), interaction mid, physics
    late (near data, when detail forms), which keeps the terms from fighting all at once."""
    early: float = 0.8
    mid: float = 0.5
    late: float = 0.15
    width: float = 0.2
    floor: float = 0.15

    def factor(self, stage: str, t: float) -> float:
        centre = getattr(self, stage)
        return self.floor + (1 - self.floor) * math.exp(-0.5 * ((t - centre) / self.width) ** 2)


@dataclass
class EnergyWeights:
    """Base weight lambda_r of each energy, chosen so that typical violations (5-10 cm off a
    target, 0.5 m/s foot slide, 2 cm penetration) contribute comparably."""
    keyframe: float = 1.0
    trajectory: float = 1.0
    object: float = 1.0
    contact: float = 1.0
    hand_contact: float = 1.0
    spacing: float = 1.0
    penetration: float = 10.0
    foot_skate: float = 0.05
    ground: float = 10.0
    smoothness: float = 20.0
    schedule: EnergySchedule = field(default_factory=EnergySchedule)

    def at(self, t: float) -> dict[str, float]:
        """lambda_r(t) for every energy name."""
        return {f.name: getattr(self, f.name) * self.schedule.factor(STAGE[f.name], t)
                for f in fields(self) if f.name in ENERGIES}


def total_energy(motion: dict[str, Tensor], ctx: EnergyContext, t: float,
                 weights: EnergyWeights | None = None, enabled: set[str] | None = None,
                 occupancy: Tensor | None = None) -> tuple[Tensor, dict[str, Tensor]]:
    """sum_r lambda_r(t) E_r over the enabled energies (None = all), at the CTMC `occupancy`
    (B, N, 3) (None: no planner, the contact terms are always on).
    Returns total (B,) and the unweighted E_r (B,) by name, for display."""
    weights = weights or EnergyWeights()
    unknown = set(enabled or ()) - set(ENERGIES)
    if unknown:
        raise ValueError(f"unknown energies {sorted(unknown)}; known: {list(ENERGIES)}")
    names = ENERGIES if enabled is None else [n for n in ENERGIES if n in enabled]
    lam = weights.at(t)
    terms = {}
    for name in names:
        if lam[name] != 0:
            terms[name] = ENERGIES[name](motion, ctx, occupancy)
        else:  # reported, but no graph to build
            with torch.no_grad():
                terms[name] = ENERGIES[name](motion, ctx, occupancy)
    if not terms:
        return motion["joints"].new_zeros(motion["joints"].shape[0]), terms
    stacked = torch.stack(list(terms.values()), -1)                          # (B, R)
    return stacked @ stacked.new_tensor([lam[name] for name in terms]), terms   # one op, not 2R
