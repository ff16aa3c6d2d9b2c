"""Energy guidance on the clean-latent estimate (paper sections 3.3-3.4).

Guidance acts on z0_hat (K, T, V, d), what the current step predicts the final latent to be: the
decoded motion's energies (engine.sampling.energies), routed to the latent through the Jacobian
surrogate B_rho (or exact autograd through the decoder when the bundle's surrogate is untrained),
plus the latent energy E_lat, move it by Polyak steps. The CTMC occupancy the planner holds at
that moment is passed in with each call.
"""
from __future__ import annotations

from typing import Callable

import torch

from ..models.alignment import latent_energy
from ..models.surrogate import exact_latent_gradient, flatten_motion
from .config import SamplerConfig
from .energies import ENERGIES, EnergyContext, EnergyWeights, total_energy
from .output import LatentDecoder

TRAJECTORY_ONLY = {"trajectory"}


class EnergyGuidance:
    def __init__(self, bundle, config: SamplerConfig, energies: EnergyContext, decode: LatentDecoder,
                 storyboard_view: Callable[[dict], dict], s2d: torch.Tensor, present: torch.Tensor):
        self.config, self.energies, self.decode = config, energies, decode
        self.storyboard_view, self.s2d, self.present = storyboard_view, s2d, present
        self.vqvae, self.latent_head = bundle.vqvae, bundle.latent_head
        # An untrained surrogate routes garbage: fall back to exact gradients through the decoder.
        self.surrogate = bundle.surrogate if "surrogate" in bundle.metadata.get("stages", ()) else None
        self.enabled = TRAJECTORY_ONLY if config.trajectory_only else set(ENERGIES)
        self.weights = EnergyWeights()

    @property
    def active(self) -> bool:
        return self.config.use_energy or self.config.use_latent

    def guide(self, z0: torch.Tensor, t: float, steps: int, occupancy: torch.Tensor | None,
              max_rate: float | None = None) -> tuple[torch.Tensor, dict[str, float]]:
        """`steps` Polyak steps of the total energy on the clean latent z0 (K, T, V, d); returns
        the moved z0 and the energies' values (means over the variations) by name.

        A Polyak step moves along the gradient g by E / |g|^2, the length that would zero the
        energy if it were linear there; damped by `guidance_alpha` and capped at an RMS of
        `guidance_max_rms` latent units, so a far-off keyframe cannot throw the latent off the
        data manifold and a satisfied storyboard leaves it alone. The energy never reaches 0
        (sketches disagree with physics a little), so near its floor E / |g|^2 grows without
        bound and the steps overshoot back and forth: a micrometre change to a stroke then
        changes the motion by centimetres. `max_rate` caps the rate, which steadies the result
        and weakens the pull (see SamplerConfig.guidance_max_rate)."""
        cfg, values = self.config, {}
        for _ in range(steps):
            energy, grad = self._energy_and_gradient(z0, t, occupancy, values)
            sq = grad.flatten(1).pow(2).sum(1).clamp_min(1e-12)
            rate = cfg.guidance_alpha * energy / sq
            if max_rate is not None:
                rate = rate.clamp(max=max_rate)
            step = rate[:, None, None, None] * grad
            rms = step.flatten(1).pow(2).mean(1).sqrt().clamp_min(1e-12)
            z0 = z0 - step * (cfg.guidance_max_rms / rms).clamp(max=1.0)[:, None, None, None]
        return z0, values

    def _energy_and_gradient(self, z0: torch.Tensor, t: float, occupancy: torch.Tensor | None,
                             values: dict[str, float]) -> tuple[torch.Tensor, torch.Tensor]:
        """Total energy (K,) at z0 and its latent gradient (K, T, V, d); per-term means go to values.
        Raw-space terms reach the latent through B_rho (exact autograd when there is none)."""
        cfg = self.config
        energy, grad = z0.new_zeros(z0.shape[0]), torch.zeros_like(z0)
        objective, leaves = 0.0, []                  # differentiated in one backward pass
        with torch.enable_grad():
            if cfg.use_energy:
                if self.surrogate is not None:   # stop at the motion (no graph through the decoder), route through B_rho
                    with torch.no_grad():
                        motion = self.decode(z0)
                    motion = {k: v.detach().requires_grad_(True) for k, v in motion.items()}
                    leaves = list(motion.values())
                else:
                    leaves = [z0.detach().requires_grad_(True)]
                    motion = self.decode(leaves[0])
                total, terms = total_energy(self.storyboard_view(motion), self.energies, t, self.weights,
                                            self.enabled, occupancy)
                objective = total.sum()
            if cfg.use_latent:
                zl = z0.detach().requires_grad_(True)
                e_lat = cfg.latent_weight * latent_energy(self.latent_head, zl, self.s2d, self.present)
                objective = objective + e_lat.sum()
                leaves.append(zl)
            grads = [torch.zeros_like(v) if g is None else g
                     for v, g in zip(leaves, torch.autograd.grad(objective, leaves, allow_unused=True))]
        if cfg.use_energy:
            if self.surrogate is None:
                grad = grad + grads[0]
            else:
                raw = dict(zip(motion, grads))
                with torch.no_grad():   # a gradient to follow, not to differentiate
                    routed = self.surrogate(raw)
                grad = grad + routed
                if cfg.check_surrogate:
                    exact = exact_latent_gradient(self.vqvae.decode, z0, flatten_motion(raw))
                    values["surrogate_cosine"] = float(
                        torch.nn.functional.cosine_similarity(routed.flatten(1), exact.flatten(1), 1).mean())
            energy = energy + total.detach()
            values.update({k: float(v.detach().mean()) for k, v in terms.items()})
        if cfg.use_latent:
            grad = grad + grads[-1]
            energy = energy + e_lat.detach()
            values["latent"] = float(e_lat.detach().mean())
        values["total"] = float(energy.mean())
        return energy, grad
