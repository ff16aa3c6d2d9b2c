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

import dataclasses
import hashlib
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import torch
from torch import nn

from ..atomic import atomic_write
from .alignment import LatentProjectionHead
from .controlnet import ParallelControlNets
from .ctmc import PhasePlanner, PhasePlannerConfig
from .encoders import EncoderConfig, SketchConditioner
from .potential import LatentPotential, PotentialConfig
from .preview import PREVIEW_STEPS
from .sketch2anim import Sketch2AnimINT
from .student import RectifiedFlowStudent
from .surrogate import JacobianSurrogate, SurrogateConfig
from .teacher import DiffusionTeacher, VPSchedule
from .unet import TemporalUNet, UNetConfig
from .vqvae import EntityVQVAE, VQVAEConfig

BUNDLE_FORMAT = "sketch2colab-bundle"
BUNDLE_VERSION = 1
DEFAULT_PATH = Path(__file__).resolve().parents[2] / "resources" / "models" / "default.pt"
BASELINES_PATH = DEFAULT_PATH.with_name("baselines.pt")
PARTS = ("vqvae", "conditioner", "latent_head", "teacher", "student", "planner", "potential", "surrogate", "preview")
# Parts a trained bundle may lack (bundles made before them): `has_part` says whether one is trained.
OPTIONAL_PARTS = ("preview",)
# The benchmark's trained comparisons, kept apart from the product (resources/models/baselines.pt,
# laid over the bundle they were trained with by `load_baselines`): the Sketch2Anim-INT baseline
# and the "parallel ControlNets" ablation's student.
BASELINE_PARTS = ("sketch2anim", "controlnet_student")
# The bundle parts each baseline was trained against: it is only valid with those very weights.
BASELINE_DEPENDS = {"sketch2anim": ("vqvae",),
                    "controlnet_student": ("vqvae", "teacher", "conditioner", "planner", "latent_head", "potential")}


class BundleError(ValueError):
    """A bundle file that is missing, corrupt, or does not fit this program's models."""


# What a bundle written before a plain ModelConfig field existed meant by it.
UNRECORDED = {"preview_steps": 4}


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
    preview_steps: int = PREVIEW_STEPS   # the jumps the preview student was distilled for

    @classmethod
    def default(cls) -> "ModelConfig":
        """Sized for the 2-core CPU product target."""
        return cls()

    def with_text(self) -> "ModelConfig":
        """The same model reading the storyboard's text too (models/text.py)."""
        width = self.encoder.text_dim
        return dataclasses.replace(self, encoder=dataclasses.replace(self.encoder, text=True),
                                   teacher_unet=dataclasses.replace(self.teacher_unet, text_dim=width),
                                   student_unet=dataclasses.replace(self.student_unet, text_dim=width))

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
            if f.default_factory is dataclasses.MISSING:   # a plain value
                out[f.name] = data.get(f.name, UNRECORDED.get(f.name, f.default))
                continue
            sub = f.default_factory()
            values = {k: tuple(v) if isinstance(getattr(sub, k, None), tuple) else v
                      for k, v in data.get(f.name, {}).items()}
            out[f.name] = dataclasses.replace(sub, **values)
        return cls(**out)


_BUILDERS = {
    "vqvae": lambda cfg: EntityVQVAE(cfg.vqvae),
    "conditioner": lambda cfg: SketchConditioner(cfg.encoder),
    "latent_head": lambda cfg: LatentProjectionHead(cfg.encoder),
    "teacher": lambda cfg: DiffusionTeacher(TemporalUNet(cfg.teacher_unet), cfg.schedule),
    "student": lambda cfg: RectifiedFlowStudent(TemporalUNet(cfg.student_unet)),
    "planner": lambda cfg: PhasePlanner(cfg.planner),
    "potential": lambda cfg: LatentPotential(cfg.potential),
    "surrogate": lambda cfg: JacobianSurrogate(cfg.surrogate),
    "preview": lambda cfg: RectifiedFlowStudent(TemporalUNet(cfg.student_unet)),
    "sketch2anim": lambda cfg: Sketch2AnimINT(cfg.teacher_unet, cfg.encoder, cfg.schedule),
    "controlnet_student": lambda cfg: RectifiedFlowStudent(ParallelControlNets(cfg.student_unet)),
}


def build_parts(cfg: ModelConfig, names: tuple[str, ...] = PARTS) -> dict[str, nn.Module]:
    """Freshly initialised modules for the parts `names` (PARTS and BASELINE_PARTS names)."""
    return {name: _BUILDERS[name](cfg) for name in names}


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
        return self.trained and name in self.parts and name not in self.metadata.get("absent_parts", ())

    def eval(self) -> "ModelBundle":
        for m in self.parts.values():
            m.eval().requires_grad_(False)
        return self

    def save(self, path: str | Path) -> None:
        """Half-precision weights (buffers that count things stay as they are), atomically."""
        absent = set(self.metadata.get("absent_parts", ()))
        meta = {k: v for k, v in self.metadata.items()
                if k not in ("absent_parts", "weights_sha256", "part_sha256")}  # found again on load
        _write(path, self.config, {n: m for n, m in self.parts.items() if n not in absent and n not in BASELINE_PARTS},
               {**meta, "trained": self.trained})


def _write(path: str | Path, config: ModelConfig, parts: dict[str, nn.Module], metadata: dict) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    weights = {name: {k: v.half() if v.is_floating_point() else v for k, v in m.state_dict().items()}
               for name, m in parts.items()}
    meta = {**metadata, "saved_at": time.strftime("%Y-%m-%d %H:%M:%S")}
    with atomic_write(path) as f:
        torch.save({"format": BUNDLE_FORMAT, "version": BUNDLE_VERSION, "config": config.to_dict(),
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


def _read(path: Path) -> tuple[ModelConfig, dict, dict, str]:
    """A bundle-format file's (config, weights, metadata, weights digest), checked; BundleError otherwise."""
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
        digest = weights_digest(weights)
    except Exception as e:  # noqa: BLE001  any malformed table is damage
        raise BundleError(f"{path}: damaged model bundle ({_first_line(e)})") from None
    if expected is not None and digest != expected:
        raise BundleError(f"{path}: the weights do not match their checksum: the file is damaged")
    try:
        cfg = ModelConfig.from_dict(data["config"])
    except Exception as e:
        raise BundleError(f"{path}: bundle config does not fit these models ({_first_line(e)})") from None
    return cfg, weights, meta, digest


def _load_weights(path: Path, parts: dict[str, nn.Module], weights: dict) -> None:
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


def load_bundle(path: str | Path) -> ModelBundle:
    """Read a bundle file; any problem raises BundleError with a one-line message."""
    path = Path(path)
    cfg, weights, meta, digest = _read(path)
    try:
        parts = build_parts(cfg)
    except Exception as e:
        raise BundleError(f"{path}: bundle config does not fit these models ({_first_line(e)})") from None
    absent = sorted(set(parts) - set(weights))
    if meta.get("trained") and set(absent) - set(OPTIONAL_PARTS):
        missing = ", ".join(sorted(set(absent) - set(OPTIONAL_PARTS)))
        raise BundleError(f"{path}: marked trained but has no weights for {missing}")
    _load_weights(path, parts, weights)
    meta = {**meta, "absent_parts": absent, "weights_sha256": digest,
            "part_sha256": {name: weights_digest({name: state}) for name, state in weights.items()}}
    return ModelBundle(cfg, parts, trained=bool(meta.get("trained", False)), metadata=meta).eval()


def save_baselines(path: str | Path, bundle: ModelBundle, parts: dict[str, nn.Module], metadata: dict) -> None:
    """Write baseline parts (BASELINE_PARTS names) trained with `bundle` (as loaded from its file),
    each tied to the digests of the bundle parts it was trained against (BASELINE_DEPENDS)."""
    if not set(parts) <= set(BASELINE_PARTS):
        raise ValueError(f"not baseline parts: {sorted(set(parts) - set(BASELINE_PARTS))}")
    digests = bundle.metadata.get("part_sha256", {})
    depends = {name: {dep: digests.get(dep) for dep in BASELINE_DEPENDS[name]} for name in parts}
    _write(path, bundle.config, parts, {**metadata, "depends_on": depends})


def load_baselines(bundle: ModelBundle, path: str | Path) -> ModelBundle:
    """`bundle` with the baseline parts of `path` added. A part trained against other weights of
    the bundle parts it depends on (a retrained teacher, say) is left out like an absent one
    (has_part False; metadata["stale_baselines"] names it): its figures would not be its own.
    The preview's jumps are no network's shape: baselines hold across a preview retrained."""
    path = Path(path)
    cfg, weights, meta, _ = _read(path)
    if replace(cfg, preview_steps=bundle.config.preview_steps).to_dict() != bundle.config.to_dict():
        raise BundleError(f"{path}: the baselines' model config differs from the bundle's")
    digests = bundle.metadata.get("part_sha256", {})
    depends = meta.get("depends_on", {})

    def current(name: str) -> bool:
        deps = depends.get(name)
        return deps is not None and all(digests.get(dep) is not None and digests[dep] == d for dep, d in deps.items())

    stale = [name for name in weights if name in BASELINE_PARTS and not current(name)]
    parts = build_parts(cfg, BASELINE_PARTS)
    _load_weights(path, parts, weights)
    for module in parts.values():
        module.eval().requires_grad_(False)
    absent = [*bundle.metadata.get("absent_parts", ()), *(n for n in BASELINE_PARTS if n not in weights or n in stale)]
    return replace(bundle, parts={**bundle.parts, **parts},
                   metadata={**bundle.metadata, "absent_parts": absent, "baselines": meta, "stale_baselines": stale})


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
