"""The Sketch2Anim-INT network (engine.baselines.sketch2anim runs it): a diffusion model in raw
motion space whose storyboard enters through keypose, trajectory and object ControlNet branches
(models/controlnet.py), with its own copy of the aligned 2D/3D sketch encoder at frame rate.

Raw motion, predicted clean as MDM does: the VQ-VAE's normalized frame features per entity
(x (B, N, 3, 201); the object's 19 zero-padded), so the baseline learns the same data with the
same normalization, without the latent. Its backbone is our teacher's U-Net configuration at
frame rate.
"""
from __future__ import annotations

from dataclasses import replace

import torch
import torch.nn.functional as F
from torch import nn

from .conditioning import Conditioning
from .controlnet import ParallelControlNets
from .encoders import EncoderConfig, SketchConditioner
from .teacher import DiffusionTeacher, VPSchedule, broadcast
from .unet import UNetConfig
from .vqvae import HUMAN_FEATURES, NUM_HUMANS, EntityVQVAE


class CleanPredictingDiffusion(DiffusionTeacher):
    """MDM's parameterization, which Sketch2Anim builds on: the backbone predicts the clean motion
    and the noise the solvers ask for is derived from it. Predicting the noise of 201 raw features
    per entity through the teacher's 48-channel U-Net could not even pass z_tau through where it is
    nearly all noise (at tau 0.95 the estimate's cosine to z_tau was 0.48; epsilon MSE 0.77 at every
    tau after 14000 steps), and DDIM's clean estimate, that error times up to 1 / sqrt(abar), put
    people metres away."""

    def clean(self, z: torch.Tensor, tau: torch.Tensor, cond: Conditioning | None = None,
              entity_pos: torch.Tensor | None = None) -> torch.Tensor:
        """Predicted clean sample (B, T, V, d) at z_tau (B, T, V, d), tau (B,)."""
        return self.backbone(z, tau, cond, entity_pos)[:, 0]

    def eps(self, z: torch.Tensor, tau: torch.Tensor, cond: Conditioning | None = None,
            entity_pos: torch.Tensor | None = None) -> torch.Tensor:
        abar = broadcast(self.schedule.alpha_bar(tau), z)
        return (z - abar.sqrt() * self.clean(z, tau, cond, entity_pos)) / (1 - abar).sqrt()

    forward = eps

    def loss(self, z0: torch.Tensor, cond: Conditioning | None, entity_pos: torch.Tensor | None = None,
             generator: torch.Generator | None = None, cond_drop: float = 0.1) -> dict[str, torch.Tensor]:
        """MSE of the clean sample at tau ~ U[tau_min, 1] (MDM's simple loss)."""
        tau, _, z_tau, cond = self.noised(z0, cond, generator, cond_drop)
        loss = (self.clean(z_tau, tau, cond, entity_pos) - z0).pow(2).mean()
        return {"loss": loss, "x0_mse": loss.detach()}


class Sketch2AnimINT(nn.Module):
    def __init__(self, unet: UNetConfig, encoder: EncoderConfig, schedule: VPSchedule):
        super().__init__()
        self.conditioner = SketchConditioner(replace(encoder, text=False))          # sketch only
        self.denoiser = CleanPredictingDiffusion(ParallelControlNets(replace(unet, latent_dim=HUMAN_FEATURES,
                                                                     cond_dim=encoder.d_model, text_dim=0)), schedule)

    @property
    def feature_dim(self) -> int:
        return HUMAN_FEATURES

    def condition(self, controls: dict[str, torch.Tensor], frames: int) -> Conditioning:
        """The storyboard's controls at frame rate (one 'latent step' per frame)."""
        return self.conditioner.encode(controls, frames, NUM_HUMANS + 1).conditioning

    @staticmethod
    def features(vqvae: EntityVQVAE, batch: dict) -> torch.Tensor:
        """Motion batch -> x (B, N, 3, 201): normalized frame features per entity."""
        human, obj = vqvae.normalized_features(batch)
        return torch.cat([human, F.pad(obj, (0, human.shape[-1] - obj.shape[-1]))], 2)

    @staticmethod
    def motion(vqvae: EntityVQVAE, x: torch.Tensor) -> dict[str, torch.Tensor]:
        """x (B, N, 3, 201) -> the motion dict of EntityVQVAE.decode."""
        return vqvae.motion_from_features(x[:, :, :NUM_HUMANS], x[:, :, NUM_HUMANS:, :vqvae.cfg.object_features])

    def loss(self, vqvae: EntityVQVAE, batch: dict, generator: torch.Generator) -> dict[str, torch.Tensor]:
        """Clean-sample loss on the raw features with 10% of the storyboards dropped."""
        with torch.no_grad():
            x0 = self.features(vqvae, batch)
        return self.denoiser.loss(x0, self.condition(batch, x0.shape[1]), None, generator=generator)
