"""The model bundle: every trained part the product needs, saved and loaded as one file.

File: a torch.save'd dict (weights_only-safe) with
  format      "sketch2colab-bundle"
  version     BUNDLE_VERSION
  config      ModelConfig as nested plain dicts
  metadata    free-form dict (stages trained, steps, data, date, metrics)
  weights     {part name: half-precision state dict}; parts absent from the file stay untrained
              (only OPTIONAL_PARTS may be absent from a trained bundle)
`load_default()` loads resources/models/default.pt, or when none is shipped returns a freshly
initialised small bundle flagged trained=False, so the app can stream (noise-like) motion
until trained weights land.
"""
from __future__ import annotations

import hashlib
import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch import nn

from ..atomic import atomic_write
from .alignment import LatentProjectionHead
from .ctmc import PhasePlanner, PhasePlannerConfig
from .encoders import EncoderConfig, SketchConditioner
from .potential import LatentPotential, PotentialConfig
from .student import RectifiedFlowStudent
from .surrogate import JacobianSurrogate, SurrogateConfig
from .teacher import DiffusionTeacher, VPSchedule
from .unet import TemporalUNet, UNetConfig
from .vqvae import EntityVQVAE, VQVAEConfig

BUNDLE_FORMAT = "sketch2colab-bundle"
BUNDLE_VERSION = 1
DEFAULT_PATH = Path(__file__).resolve().parents[2] / "resources" / "models" / "default.pt"
PARTS = ("vqvae", "conditioner", "latent_head", "teacher", "student", "planner", "potential", "surrogate", "preview")
# Parts a trained bundle may lack (bundles made before them): `has_part` says whether one is trained.
OPTIONAL_PARTS = ("preview",)


class BundleError(ValueError):
    """A bundle file that is missing, corrupt, or does not fit this program's models."""


@dataclass
class ModelConfig:
    vqvae: VQVAEConfig = field(default_factory=VQVAEConfig)
    teacher_unet: UNetConfig = field(default_factory=UNetConfig.default)
    student_unet: UNetConfig = field(default_factory=lambda: UNetConfig.default(n_heads_out=3))
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    planner: PhasePlannerConfig = field(default_factory=PhasePlannerConfig)
    potential: PotentialConfig = field(default_factory=PotentialConfig)
    surrogate: SurrogateConfig = field(default_factory=SurrogateConfig)
    schedule: VPSchedule = field(default_factory=VPSchedule)

    @classmethod
    def default(cls) -> "ModelConfig":
        """Sized for the 2-core CPU product target."""
        return cls()

    @classmethod
    def large(cls) -> "ModelConfig":
        """Wider networks for GPU training (the latent interface stays the same)."""
        return cls(vqvae=VQVAEConfig(channels=256, codebook_size=1024),
                   teacher_unet=UNetConfig.large(), student_unet=UNetConfig.large(n_heads_out=3),
                   encoder=EncoderConfig(hidden=256))

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "ModelConfig":
        out = {}
        for f in dataclasses.fields(cls):
            sub = f.default_factory()
            values = {k: tuple(v) if isinstance(getattr(sub, k, None), tuple) else v
                      for k, v in data.get(f.name, {}).items()}
            out[f.name] = dataclasses.replace(sub, **values)
        return cls(**out)


def build_parts(cfg: ModelConfig) -> dict[str, nn.Module]:
    """Freshly initialised modules for every part, keyed by PARTS names."""
    return {
        "vqvae": EntityVQVAE(cfg.vqvae),
        "conditioner": SketchConditioner(cfg.encoder),
        "latent_head": LatentProjectionHead(cfg.encoder),
        "teacher": DiffusionTeacher(TemporalUNet(cfg.teacher_unet), cfg.schedule),
        "student": RectifiedFlowStudent(TemporalUNet(cfg.student_unet)),
        "planner": PhasePlanner(cfg.planner),
        "potential": LatentPotential(cfg.potential),
        "surrogate": JacobianSurrogate(cfg.surrogate),
        "preview": RectifiedFlowStudent(TemporalUNet(cfg.student_unet)),
    }


@dataclass
class ModelBundle:
    config: ModelConfig
    parts: dict[str, nn.Module]
    trained: bool = False                     # False: untrained weights, output is not motion
    metadata: dict = field(default_factory=dict)

    def __getattr__(self, name: str):
        parts = self.__dict__.get("parts", {})
        if name in parts:
            return parts[name]
        raise AttributeError(name)

    def has_part(self, name: str) -> bool:
        """Whether `name` holds trained weights (an optional part may be absent from the file)."""
        return self.trained and name not in self.metadata.get("absent_parts", ())

    def eval(self) -> "ModelBundle":
        for m in self.parts.values():
            m.eval().requires_grad_(False)
        return self

    def save(self, path: str | Path) -> None:
        """Half-precision weights (buffers that count things stay as they are), atomically."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        absent = set(self.metadata.get("absent_parts", ()))
        weights = {name: {k: v.half() if v.is_floating_point() else v for k, v in m.state_dict().items()}
                   for name, m in self.parts.items() if name not in absent}
        meta = {**{k: v for k, v in self.metadata.items() if k != "absent_parts"},   # found again on load
                "trained": self.trained, "saved_at": time.strftime("%Y-%m-%d %H:%M:%S")}
        with atomic_write(path) as f:
            torch.save({"format": BUNDLE_FORMAT, "version": BUNDLE_VERSION, "config": self.config.to_dict(),
                        "metadata": meta, "weights": weights, "weights_sha256": weights_digest(weights)}, f)


def weights_digest(weights: dict[str, dict[str, torch.Tensor]]) -> str:
    """SHA-256 of every tensor's name, dtype, shape and bytes, in a fixed order: a flipped byte
    in a weight changes it (a damaged file loaded silently and moved the motion by 0.5 m)."""
    digest = hashlib.sha256()
    for name in sorted(weights):
        for key in sorted(weights[name]):
            tensor = weights[name][key]
            if not isinstance(tensor, torch.Tensor):
                raise BundleError(f"weight {name}/{key} is not a tensor")
            tensor = tensor.detach().cpu().contiguous()
            digest.update(f"{name}/{key}/{tensor.dtype}/{tuple(tensor.shape)}".encode())
            digest.update(tensor.reshape(-1).view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


def _first_line(error: Exception) -> str:
    return (str(error).splitlines() or [type(error).__name__])[0][:160]


def load_bundle(path: str | Path) -> ModelBundle:
    """Read a bundle file; any problem raises BundleError with a one-line message."""
    path = Path(path)
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise BundleError(f"{path}: no such model bundle") from None
    except Exception as e:  # zip, pickle and torch errors all mean "not a bundle we can read"
        raise BundleError(f"{path}: not a readable model bundle ({type(e).__name__}: {_first_line(e)})") from None
    if not isinstance(data, dict) or data.get("format") != BUNDLE_FORMAT:
        raise BundleError(f"{path}: not a Sketch2Colab model bundle")
    version = data.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= BUNDLE_VERSION:
        raise BundleError(f"{path}: bundle version {version!r} is not one this program reads (1 to {BUNDLE_VERSION})")
    weights, meta = data.get("weights"), data.get("metadata", {})
    if not isinstance(weights, dict) or not isinstance(meta, dict) or not isinstance(data.get("config"), dict):
        raise BundleError(f"{path}: damaged model bundle (its weights, metadata or config are not tables)")
    expected = data.get("weights_sha256")
    try:
        intact = expected is None or weights_digest(weights) == expected
    except Exception as e:  # noqa: BLE001  any malformed table is damage
        raise BundleError(f"{path}: damaged model bundle ({_first_line(e)})") from None
    if not intact:
        raise BundleError(f"{path}: the weights do not match their checksum: the file is damaged")
    try:
        cfg = ModelConfig.from_dict(data["config"])
        parts = build_parts(cfg)
    except Exception as e:
        raise BundleError(f"{path}: bundle config does not fit these models ({_first_line(e)})") from None
    absent = sorted(set(parts) - set(weights))
    if meta.get("trained") and set(absent) - set(OPTIONAL_PARTS):
        missing = ", ".join(sorted(set(absent) - set(OPTIONAL_PARTS)))
        raise BundleError(f"{path}: marked trained but has no weights for {missing}")
    for name, state in weights.items():
        if name not in parts:
            raise BundleError(f"{path}: unknown part {name!r} in bundle")
        try:
            target = parts[name].state_dict()
            parts[name].load_state_dict({k: v.to(target[k].dtype) if k in target else v for k, v in state.items()})
        except Exception as e:
            raise BundleError(f"{path}: weights of part {name!r} do not fit ({_first_line(e)})") from None
        bad = [k for k, v in state.items() if v.is_floating_point() and not torch.isfinite(v).all()]
        if bad:
            raise BundleError(f"{path}: part {name!r} has non-finite weights in {bad[0]}")
    meta = {**meta, "absent_parts": absent}
    return ModelBundle(cfg, parts, trained=bool(meta.get("trained", False)), metadata=meta).eval()


def untrained_bundle(cfg: ModelConfig | None = None, seed: int = 0) -> ModelBundle:
    """A freshly initialised bundle (trained=False) with a fixed seed, for streaming before
    trained weights exist and for tests."""
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        parts = build_parts(cfg or ModelConfig.default())
    return ModelBundle(cfg or ModelConfig.default(), parts, trained=False,
                       metadata={"note": "untrained: freshly initialised weights"}).eval()


def load_default(path: str | Path | None = None) -> ModelBundle:
    """The shipped bundle, or an untrained one when none is shipped. A shipped file that is
    broken raises BundleError (never silently replaced by untrained weights)."""
    path = Path(path) if path is not None else DEFAULT_PATH
    if not path.exists():
        return untrained_bundle()
    return load_bundle(path)
