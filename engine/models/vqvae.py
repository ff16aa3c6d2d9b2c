"""Hierarchical (residual) VQ-VAE entity latent: motion of 2 humans + 1 object <-> z (T_lat, V, d).

One token per entity (V = H + O = 3: human 0, human 1, the object slot). Each entity's frame
features are projected by an entity-type-specific layer, then a shared 1D temporal conv stack
downsamples time by 4 (N = 120 -> T_lat = 30). L residual quantizer levels each snap what the
previous levels left over to a codebook; the continuous latent the generative models see is
the sum of the level codes z = sum_l z^(l), divided by `latent_std` so that it has unit variance.

Frame features per entity (all in metres, Y up):
  human  (201): pelvis position (3), joints relative to the pelvis (22*3), local 6D rotations (22*6)
  object  (19): translation (3), quaternion wxyz (4), anchors relative to the translation (K*3, K=4)
Normalization: per-channel mean / std over the training data, stored as buffers (`fit_normalizer`);
std is floored at 1 cm so that constant channels (the pelvis' own offset) do not blow up.
An absent object (obj_present = 0) enters as zero features and is left out of every loss.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.distributed as dist
import torch.nn.functional as F
from torch import nn

from ..objects import NUM_ANCHORS
from ..skeleton import NUM_JOINTS

NUM_HUMANS = 2
NUM_OBJECTS = 1
NUM_ENTITIES = NUM_HUMANS + NUM_OBJECTS
HUMAN_FEATURES = 3 + NUM_JOINTS * 3 + NUM_JOINTS * 6
STD_FLOOR = 0.01


@dataclass
class VQVAEConfig:
    latent_dim: int = 32          # d of the entity latent
    channels: int = 128           # width of the conv stacks
    levels: int = 4               # residual quantizer levels L
    codebook_size: int = 512      # K_l, the same for every level
    downsample_stages: int = 2    # each halves time: 2 -> x4
    anchors_per_object: int = NUM_ANCHORS
    commitment: float = 0.25
    codebook_decay: float = 0.99  # EMA codebook updates
    dead_threshold: float = 0.03  # EMA assignments per batch below which a code is restarted
    joint_loss_weight: float = 30.0  # loss on world joints (metres^2): the root is 3 of 201 normalised
                                     # channels, so without it the feature loss tolerates ~10 cm root drift
    lowres_loss_weight: float = 0.1

    @property
    def object_features(self) -> int:
        return 7 + 3 * self.anchors_per_object

    @property
    def time_factor(self) -> int:
        return 2 ** self.downsample_stages


@dataclass
class Quantized:
    z: torch.Tensor            # (B, T_lat, V, d) straight-through sum of level codes
    codes: torch.Tensor        # (B, T_lat, V, L) code indices per level
    commitment: torch.Tensor   # scalar
    perplexity: torch.Tensor   # (L,) codebook perplexity per level (usage breadth)


class FeatureNormalizer(nn.Module):
    def __init__(self, human_dim: int, object_dim: int):
        super().__init__()
        self.register_buffer("human_mean", torch.zeros(human_dim))
        self.register_buffer("human_std", torch.ones(human_dim))
        self.register_buffer("object_mean", torch.zeros(object_dim))
        self.register_buffer("object_std", torch.ones(object_dim))

    @torch.no_grad()
    def fit(self, human: torch.Tensor, obj: torch.Tensor, obj_present: torch.Tensor) -> None:
        """human (B, N, H, Fh), obj (B, N, O, Fo), obj_present (B,)."""
        h = human.reshape(-1, human.shape[-1])
        self.human_mean.copy_(h.mean(0))
        self.human_std.copy_(h.std(0).clamp_min(STD_FLOOR))
        o = obj[obj_present > 0.5].reshape(-1, obj.shape[-1])
        if len(o) > 1:
            self.object_mean.copy_(o.mean(0))
            self.object_std.copy_(o.std(0).clamp_min(STD_FLOOR))


class ResidualConv(nn.Module):
    def __init__(self, channels: int):
        super().__init__()
        self.conv1 = nn.Conv1d(channels, channels, 3, padding=1)
        self.conv2 = nn.Conv1d(channels, channels, 3, padding=1)

    def forward(self, x):
        return x + self.conv2(F.silu(self.conv1(F.silu(x))))


class CodebookLevel(nn.Module):
    """One quantizer level with an EMA-updated codebook, usage tracking and dead-code restarts."""

    def __init__(self, size: int, dim: int, decay: float, dead_threshold: float):
        super().__init__()
        self.decay, self.dead_threshold = decay, dead_threshold
        self.register_buffer("codebook", torch.randn(size, dim) * 0.1)
        self.register_buffer("usage", torch.zeros(size))           # EMA assignments per batch
        self.register_buffer("code_sum", torch.zeros(size, dim))
        self.register_buffer("initialized", torch.tensor(False))
        self.register_buffer("restarts", torch.tensor(0))           # total codes restarted

    def forward(self, r: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """r (M, d) -> (codes (M, d) without gradient path, indices (M,))."""
        dist2 = (r.pow(2).sum(1, keepdim=True) - 2 * r @ self.codebook.t()
                 + self.codebook.pow(2).sum(1)[None])
        idx = dist2.argmin(1)
        if self.training:
            self._update(r.detach(), idx)
        return self.codebook[idx], idx

    @torch.no_grad()
    def _update(self, r: torch.Tensor, idx: torch.Tensor) -> None:
        if not bool(self.initialized):
            # Start from data so that no code begins far from every encoder output.
            self.codebook.copy_(r[torch.randint(len(r), (len(self.codebook),), device=r.device)])
            self.code_sum.zero_()
            self.initialized.fill_(True)
            idx = ((r[:, None] - self.codebook[None]).pow(2).sum(-1)).argmin(1)
        onehot = F.one_hot(idx, len(self.codebook)).to(r.dtype)
        counts, sums = onehot.sum(0), onehot.t() @ r
        if dist.is_available() and dist.is_initialized():
            dist.all_reduce(counts)
            dist.all_reduce(sums)
        self.usage.mul_(self.decay).add_(counts, alpha=1 - self.decay)
        self.code_sum.mul_(self.decay).add_(sums, alpha=1 - self.decay)
        used = self.usage > 1e-8
        self.codebook[used] = self.code_sum[used] / self.usage[used, None]
        dead = self.usage < self.dead_threshold
        if dead.any():
            # Restart dead codes on random current residuals (small jitter keeps them distinct).
            n = int(dead.sum())
            pick = r[torch.randint(len(r), (n,), device=r.device)]
            self.codebook[dead] = pick + 1e-3 * torch.randn_like(pick)
            self.usage[dead] = self.dead_threshold
            self.code_sum[dead] = self.codebook[dead] * self.dead_threshold
            self.restarts += n


class ResidualQuantizer(nn.Module):
    def __init__(self, cfg: VQVAEConfig):
        super().__init__()
        self.commitment = cfg.commitment
        self.levels = nn.ModuleList(CodebookLevel(cfg.codebook_size, cfg.latent_dim, cfg.codebook_decay,
                                                  cfg.dead_threshold) for _ in range(cfg.levels))

    def forward(self, e: torch.Tensor) -> Quantized:
        """e (B, T, V, d) continuous encoder output."""
        flat = e.reshape(-1, e.shape[-1])
        residual, total = flat, torch.zeros_like(flat)
        commit, codes, perplexity = flat.new_zeros(()), [], []
        for level in self.levels:
            q, idx = level(residual.detach())
            commit = commit + F.mse_loss(residual, q)
            total = total + q
            residual = residual - q
            codes.append(idx)
            p = torch.bincount(idx, minlength=len(level.codebook)).float() / len(idx)
            perplexity.append(torch.exp(-(p * torch.log(p + 1e-10)).sum()))
        z = flat + (total - flat).detach()  # straight-through: gradients skip the snapping
        return Quantized(z=z.reshape(e.shape), codes=torch.stack(codes, -1).reshape(*e.shape[:-1], -1),
                         commitment=self.commitment * commit, perplexity=torch.stack(perplexity))


class EntityVQVAE(nn.Module):
    num_entities = NUM_ENTITIES

    def __init__(self, cfg: VQVAEConfig | None = None):
        super().__init__()
        self.cfg = cfg = cfg or VQVAEConfig()
        c, fo = cfg.channels, cfg.object_features
        self.normalizer = FeatureNormalizer(HUMAN_FEATURES, fo)
        self.register_buffer("latent_std", torch.tensor(1.0))
        self.human_in, self.object_in = nn.Linear(HUMAN_FEATURES, c), nn.Linear(fo, c)
        self.entity_embed = nn.Parameter(torch.zeros(NUM_ENTITIES, c))
        down = [ResidualConv(c)]
        for _ in range(cfg.downsample_stages):
            down += [nn.Conv1d(c, c, 4, stride=2, padding=1), ResidualConv(c)]
        self.encoder = nn.Sequential(*down, nn.SiLU(), nn.Conv1d(c, cfg.latent_dim, 1))
        self.quantizer = ResidualQuantizer(cfg)
        up = [nn.Conv1d(cfg.latent_dim, c, 3, padding=1), ResidualConv(c)]
        for _ in range(cfg.downsample_stages):
            up += [nn.Upsample(scale_factor=2, mode="nearest"), nn.Conv1d(c, c, 3, padding=1), ResidualConv(c)]
        self.decoder = nn.Sequential(*up, nn.SiLU())
        self.entity_embed_dec = nn.Parameter(torch.zeros(NUM_ENTITIES, c))
        self.human_out, self.object_out = nn.Linear(c, HUMAN_FEATURES), nn.Linear(c, fo)
        self.lowres_head = nn.Linear(cfg.latent_dim, 3)

    # -- features ---------------------------------------------------------------------------
    def features(self, batch: dict) -> tuple[torch.Tensor, torch.Tensor]:
        """Raw frame features: human (B, N, 2, 201), object (B, N, 1, 13), both unnormalized."""
        joints, rot6d = batch["joints"], batch["rot6d"]
        root = joints[..., 0, :]
        human = torch.cat([root, (joints - root[..., None, :]).flatten(-2), rot6d.flatten(-2)], -1)
        pose, anchors = batch["obj_pose"], batch["obj_anchors"]
        obj = torch.cat([pose, (anchors - pose[..., None, :3]).flatten(-2)], -1)
        return human, obj

    def normalized_features(self, batch: dict) -> tuple[torch.Tensor, torch.Tensor]:
        """features() normalized per channel; an absent object's are zero."""
        human, obj = self.features(batch)
        n = self.normalizer
        present = batch["obj_present"].reshape(-1, 1, 1, 1).to(obj.dtype)
        return (human - n.human_mean) / n.human_std, (obj - n.object_mean) / n.object_std * present

    def motion_from_features(self, human: torch.Tensor, obj: torch.Tensor) -> dict[str, torch.Tensor]:
        """Normalized frame features, human (B, N, 2, 201) and object (B, N, 1, 19), -> the motion
        dict decode() returns (the inverse of normalized_features, quaternions made unit)."""
        n = self.normalizer
        human, obj = human * n.human_std + n.human_mean, obj * n.object_std + n.object_mean
        root = human[..., :3]
        local = human[..., 3:3 + NUM_JOINTS * 3].unflatten(-1, (NUM_JOINTS, 3))
        rot6d = human[..., 3 + NUM_JOINTS * 3:].unflatten(-1, (NUM_JOINTS, 6))
        quat = obj[..., 3:7] / obj[..., 3:7].norm(dim=-1, keepdim=True).clamp_min(1e-6)
        anchors = obj[..., None, :3] + obj[..., 7:].unflatten(-1, (self.cfg.anchors_per_object, 3))
        return {"joints": root[..., None, :] + local, "rot6d": rot6d,
                "obj_pose": torch.cat([obj[..., :3], quat], -1), "obj_anchors": anchors}

    def fit_normalizer(self, batch: dict) -> None:
        """Set the per-channel mean / std from a (large) batch of training items."""
        human, obj = self.features(batch)
        self.normalizer.fit(human, obj, batch["obj_present"])

    # -- encoder ----------------------------------------------------------------------------
    def encode_continuous(self, batch: dict) -> torch.Tensor:
        """Motion batch -> pre-quantization latent e (B, T_lat, V, d)."""
        human, obj = self.normalized_features(batch)
        x = torch.cat([self.human_in(human), self.object_in(obj)], 2) + self.entity_embed  # (B, N, V, C)
        b, frames, v, c = x.shape
        if frames % self.cfg.time_factor:
            raise ValueError(f"frame count {frames} is not a multiple of {self.cfg.time_factor}")
        e = self.encoder(x.permute(0, 2, 3, 1).reshape(b * v, c, frames))
        return e.reshape(b, v, -1, e.shape[-1]).permute(0, 3, 1, 2)

    def quantize(self, e: torch.Tensor) -> Quantized:
        return self.quantizer(e)

    def encode(self, batch: dict) -> torch.Tensor:
        """Motion batch -> the generative models' latent z (B, T_lat, V, d) (quantized, unit scale)."""
        return self.quantize(self.encode_continuous(batch)).z / self.latent_std

    # -- decoder ----------------------------------------------------------------------------
    def decode(self, z: torch.Tensor) -> dict[str, torch.Tensor]:
        """z (B, T_lat, V, d) unit-scale latent -> motion dict with N = 4 T_lat frames:
        joints (B,N,2,22,3), rot6d (B,N,2,22,6), obj_pose (B,N,1,7) unit quaternion,
        obj_anchors (B,N,1,K,3). Differentiable."""
        b, t, v, d = z.shape
        h = self.decoder((z * self.latent_std).permute(0, 2, 3, 1).reshape(b * v, d, t))
        h = h.reshape(b, v, h.shape[1], -1).permute(0, 3, 1, 2) + self.entity_embed_dec  # (B, N, V, C)
        return self.motion_from_features(self.human_out(h[:, :, :NUM_HUMANS]), self.object_out(h[:, :, NUM_HUMANS:]))

    def decode_lowres(self, z: torch.Tensor) -> torch.Tensor:
        """z (B, T_lat, V, d) -> entity root positions (B, T_lat, V, 3) in metres (pelvis for
        humans, translation for the object): a cheap linear head for the entity-distance bias."""
        return self.lowres_head(z * self.latent_std)

    def lowres_target(self, batch: dict) -> torch.Tensor:
        """(B, T_lat, V, 3) root positions averaged over each latent step's frames."""
        roots = torch.cat([batch["joints"][..., 0, :], batch["obj_pose"][..., :3]], 2)  # (B, N, V, 3)
        b, frames, v, _ = roots.shape
        return roots.reshape(b, frames // self.cfg.time_factor, self.cfg.time_factor, v, 3).mean(2)

    # -- training ---------------------------------------------------------------------------
    def loss(self, batch: dict) -> dict[str, torch.Tensor]:
        """Reconstruction + commitment + low-res head losses. Returns terms; 'loss' is the total."""
        q = self.quantize(self.encode_continuous(batch))
        out = self.decode(q.z / self.latent_std)
        human_t, obj_t = self.features(batch)
        human_p, obj_p = self.features(out)
        n = self.normalizer
        present = batch["obj_present"].reshape(-1, 1, 1, 1).to(obj_t.dtype)
        recon_h = ((human_p - human_t) / n.human_std).pow(2).mean()
        obj_err = ((obj_p - obj_t) / n.object_std).pow(2) * present
        recon_o = obj_err.sum() / (present.sum() * obj_err[0].numel()).clamp_min(1.0)
        joint = (out["joints"] - batch["joints"]).pow(2).sum(-1).mean()
        low_err = (self.decode_lowres(q.z.detach() / self.latent_std) - self.lowres_target(batch)).pow(2).sum(-1)
        low_mask = torch.ones_like(low_err)
        low_mask[:, :, NUM_HUMANS:] = present[:, :, 0]
        lowres = (low_err * low_mask).sum() / low_mask.sum()
        cfg = self.cfg
        total = recon_h + recon_o + cfg.joint_loss_weight * joint + q.commitment + cfg.lowres_loss_weight * lowres
        return {"loss": total, "recon_human": recon_h.detach(), "recon_object": recon_o.detach(),
                "commit": q.commitment.detach(), "lowres": lowres.detach(),
                "joint_error_m": mean_joint_error(out["joints"], batch["joints"]).detach(),
                "perplexity": q.perplexity.mean().detach()}

    @torch.no_grad()
    def calibrate_latent_scale(self, batch: dict) -> float:
        """Set `latent_std` so that encode(batch) has unit standard deviation; returns it."""
        was = self.training
        self.eval()
        self.latent_std.fill_(1.0)
        std = float(self.encode(batch).std().clamp_min(1e-4))
        self.latent_std.fill_(std)
        self.train(was)
        return std


def mean_joint_error(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean Euclidean joint error in metres. pred, target: (..., 22, 3) -> scalar."""
    return (pred - target).norm(dim=-1).mean()
