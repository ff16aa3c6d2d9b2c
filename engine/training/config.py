"""Training configuration: `default` for the 2-core CPU, `large` for a GPU."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..models.bundle import ModelConfig

STAGES = ("vqvae", "encoders", "teacher", "student1", "potential", "ctmc", "surrogate", "student2", "preview")
# The parts each stage's final.pt holds (later stages win where two hold one).
STAGE_PARTS = {"vqvae": ("vqvae",), "encoders": ("conditioner",), "teacher": ("teacher", "conditioner"),
               "student1": ("student",), "potential": ("potential",), "ctmc": ("planner",),
               "surrogate": ("surrogate",), "student2": ("student", "planner", "latent_head"),
               "preview": ("preview",)}
OPTIONAL_STAGES = {"preview": "preview"}     # stage -> the optional bundle part it trains
# The benchmark's trained comparisons (never part of `train all` or the product's bundle): the
# Sketch2Anim-INT baseline (budget: the teacher's), and the parallel-ControlNets ablation's student
# trained as ours is (controlnet1 = student1's objective and budget, controlnet2 = student2's).
BASELINE_STAGES = ("sketch2anim", "controlnet1", "controlnet2")
BASELINE_STAGE_PARTS = {"sketch2anim": ("sketch2anim",), "controlnet1": ("controlnet_student",),
                        "controlnet2": ("controlnet_student",)}


@dataclass
class TrainConfig:
    steps: int = 2000
    batch_size: int = 16
    lr: float = 2e-4
    warmup_steps: int = 100          # linear warm-up, then constant (so resuming never changes the schedule)
    weight_decay: float = 0.01
    ema_decay: float = 0.999
    grad_clip: float = 1.0
    seed: int = 0
    checkpoint_every_s: float = 180.0
    stage_seconds: float | None = None   # wall-clock budget of one stage run: it stops early, saved (resume goes on)
    warm_start: bool = False         # a fresh run starts from the stage's own final.pt where there is one (fine-tuning)
    log_every: int = 10
    num_workers: int = 0
    threads: int | None = None       # torch CPU threads (None: engine.cpu chooses, and re-chooses as load changes)
    surrogate_init_latents: int = 8  # data latents whose decoder Jacobians initialise B_rho
    model: ModelConfig = field(default_factory=ModelConfig.default)
    stage_lr: dict = field(default_factory=lambda: {"vqvae": 5e-4, "student1": 1e-4, "student2": 1e-4,
                                                    "surrogate": 1e-5, "preview": 5e-5,
                                                    "controlnet1": 1e-4, "controlnet2": 1e-4})
    stage_steps: dict = field(default_factory=dict)   # per-stage overrides of `steps` (stage "all")

    def lr_for(self, stage: str) -> float:
        return self.stage_lr.get(stage, self.lr)

    def steps_for(self, stage: str) -> int:
        return self.stage_steps.get(stage, self.steps)


def default_config() -> TrainConfig:
    return TrainConfig()


def large_config() -> TrainConfig:
    """The paper's settings (batch 64, EMA 0.999, lr 2e-4 teacher / 1e-4 student) on a GPU."""
    return TrainConfig(steps=400_000, batch_size=64, num_workers=8, checkpoint_every_s=600.0,
                       model=ModelConfig.large(), stage_steps={"student1": 250_000, "student2": 250_000})


CONFIGS = {"default": default_config, "large": large_config}
