"""What a generation is asked to do (SamplerConfig), and the one place that builds it from a
person's choices: the command line, the app's settings and the demo call `sampler_config`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

METHODS = ("student", "teacher-ddpm", "teacher-ddim")
# guidance_max_rate of "steady" generation (the app's Steady checkbox, generate --steady);
# BENCHMARKS.md compares it with the default ("Ours, steady"; stroke-nudge stability).
STEADY_GUIDANCE_RATE = 5.0
# Heun steps of the full generation. Measured after finishing on 40 held-out synthesized and 20
# artist-style storyboards, means of two seeds: 30 -> 10 steps keep K3D (3.4 -> 3.3 cm) and
# T3D (synthesized 7.1 -> 7.3, artist-style 14.0 -> 14.4 cm); FID rises 0.108 -> 0.123
# (artist-style 0.455 -> 0.458); a generation takes 0.31 instead of 0.79 s. 10 -> 9 steps with
# one final energy step instead of two (text model; 20 synthesized, 20 artist-style, 40 sketch +
# text, 3 real storyboards, one run): K3D 3.3 -> 3.4 cm, T3D 6.9 -> 6.8 cm, artist-style Pop
# 8.3 -> 8.8 cm and lowest foot 5.6 -> 6.0 cm, sketch + text unchanged; 18% less CPU time per
# generation (issue 20's 20x). 9 -> 5 steps, re-planning every 2nd step (shipped bundle, 20
# synthesized, 20 artist-style, 20 sketch + text and 3 real storyboards, seeds 0 and 1): K3D
# 3.2 -> 3.3 cm, T3D 5.6 -> 5.7 cm, real MPJPE 24.1 -> 23.7 cm and pelvis 19.8 -> 19.4 cm,
# artist-style pops within 5 cm 26 -> 26 of 40, but skate over 3% 0 -> 3 of 40 (mean 0.3 -> 0.5%)
# and the real windows' largest pops 5.3 -> 6.1 cm (mean; within 5 cm 3 -> 1 of 6); on
# artist_check's 100 storyboards (scenes 0-49, seed 0, with feet._lift_glides) pops within 5 cm
# 59 -> 55, skate within 3% 96 -> 98, penetration within 2 cm 70 -> 72;
# 25% less time (the bundled examples on a quiet machine 0.30-0.37 -> 0.23-0.26 s, the DDPM-1000
# teacher 5.3-5.5 s: 16-18x -> 21-23x). Re-planning every 3rd step, or the preview student's
# first jump before 3-5 Heun steps, missed real motion by 1.6-4.2 cm more (MPJPE).
# BENCHMARKS.md shows "Ours, 30 steps" beside the default in every protocol.
DEFAULT_STEPS = 5


class SamplerError(ValueError):
    """A request the sampler cannot serve (one line, for the user)."""


@dataclass
class SamplerConfig:
    steps: int = DEFAULT_STEPS      # Heun steps (student) or DDIM steps (teacher-ddim)
    few_step: bool = False          # the distilled preview student's PREVIEW_STEPS jumps instead
                                    # of the student's Heun steps (models/preview.py)
    seed: int = 0
    cfg: float = 1.6                # classifier-free guidance weight
    text_cfg: float | None = None   # the text's own guidance weight (None: cfg's; sampling/cfg.py). On
                                    # thumbnails with a caption (40 storyboards, seeds 0/1) 5 moved the
                                    # motion 0.29/0.27 m from the text-less one, not 0.12/0.11; R-text@3
                                    # 0.41/0.41 -> 0.47/0.41, FID 0.35/0.40 -> 0.31/0.37; on full
                                    # sketches the text moves it 4 cm either way. A third more network
                                    # time where there is a text, so not the default.
    method: str = "student"
    student_part: str = "student"   # the bundle part the student method integrates
                                    # ("controlnet_student": the parallel-ControlNets ablation)
    variations: int = 1             # K samples drawn at once (one batch)
    use_energy: bool = True         # raw-space energy guidance (ablation "w/o Energy")
    use_ctmc: bool = True           # CTMC mixing of sub-fields and contact gating ("w/o CTMC")
    use_latent: bool = True         # latent grounding E_lat ("w/o latent grounding")
    use_temporal_bias: bool = True  # trajectory attention bias ("w/o temporal bias")
    use_text: bool = True           # the storyboard's text, for a model that reads it ("sketch only")
    trajectory_only: bool = False   # only the trajectory energy ("trajectory-only")
    ctmc_every: int = 2             # re-plan the phases after every k-th step (0: on the result only)
    guidance_steps: int = 1         # energy steps on z0_hat per solver step
    guidance_start: float = 0.7     # guide only once t <= this (near noise the network re-predicts
                                    # z0_hat almost regardless of z, so early guidance is mostly lost)
    guidance_alpha: float = 1.0     # damping of the Polyak step (1: the full linearised step)
    guidance_max_rms: float = 0.25  # cap on one step's RMS change, latent units
    guidance_max_rate: float | None = None  # cap on the Polyak rate E / |g|^2 during the ODE
                                    # (STEADY_GUIDANCE_RATE: steadier under edits, more foot skate)
    latent_weight: float = 0.01     # eta_lat, weight of E_lat against the raw energies (f_gamma's
                                    # regression pulls towards an average motion: at 0.05, K3D +0.4 cm)
    final_refine_steps: int = 1     # extra energy steps on the final latent (physics stage; 2 before the
                                    # 9 steps, see DEFAULT_STEPS; 4 measured no better than 2)
    langevin_steps: int = 0         # micro-Langevin with the teacher score (paper: 3)
    langevin_step_size: float = 1e-3
    finish: bool = True             # engine.finishing on the final clips ("w/o finishing")
    polish: bool = True             # with its clean-up passes (FinishConfig.polish; a preview's go without)
    check_surrogate: bool = False   # also take the exact gradient through the decoder and report
                                    # its cosine to B_rho's as the energy "surrogate_cosine" (slower)
    threads: int | None = None      # torch threads (None: engine.cpu chooses from the free cores, and
                                    # re-chooses between steps as other programs' load changes)
    reserve_cores: float = 0.0      # cores to leave to the caller's own other work (the app's drawing)

    def check(self) -> None:
        """SamplerError for settings no generation can run with."""
        if self.method not in METHODS:
            raise SamplerError(f"unknown method {self.method!r}; choose one of {', '.join(METHODS)}")
        if self.steps < 1 or self.variations < 1:
            raise SamplerError("steps and variations must be at least 1")
        if self.text_cfg is not None and not self.text_cfg >= 0:
            raise SamplerError(f"the text's guidance weight must be 0 or more, not {self.text_cfg}")


def sampler_config(*, method: str = "student", steps: int = DEFAULT_STEPS, seed: int = 0, cfg: float = 1.6,
                   variations: int = 1, energy: bool = True, ctmc: bool = True, finish: bool = True,
                   steady: bool = False, preview: bool = False, threads: int | None = None,
                   reserve_cores: float = 0.0, text_cfg: float | None = None) -> SamplerConfig:
    """A SamplerConfig from the choices a person makes (checked: SamplerError on a bad one).
    `preview`: the fast path for motion that follows the pointer (steps and cfg unused): the
    preview student's jumps (ModelConfig.preview_steps), no energy guidance, the phases planned on
    the result only, finished without the clean-up (FinishConfig.polish). On 25 held-out
    storyboards (10 synthesized, 3 real, 12 artist-style), against the 4-jump preview with its last
    jump guided and the whole finishing: keys and paths as close (K2D 1.2 / 2.3 / 4.2 cm, T2D
    2.8 / 3.4 / 4.2 cm, where the full generation's are 1.1 / 2.1 / 4.2 and 2.6 / 2.6 / 4.2), larger
    pops (the largest per clip 6.0 / 10.2 / 7.3 cm against 4.8 / 5.3 / 4.8) and hands off grips
    too low to reach without the crouch (2.6 cm on the artist-style ones). On the let_go example
    (0.24 -> 0.11 s): the clean-up is 89 ms of it, 2 jumps instead of 4 save 17 ms, no guidance
    22 ms (the latent term alone, guidance's cheap part, made it worse: pops 7.7 cm, K2D 1.4 cm),
    one plan instead of two 9 ms (keys and grips unchanged to 0.4 mm). Kept in: the skeleton fit's
    smoothing (without it, with the latent term on, the pops were 10.1 cm, not 7.7) and the held
    box pushed out of the bodies (penetration 6.2 cm without, not 2.3).
    """
    config = SamplerConfig(steps=steps, seed=seed, cfg=cfg, text_cfg=text_cfg, method=method, variations=variations,
                           use_energy=energy, use_ctmc=ctmc, finish=finish,
                           guidance_max_rate=STEADY_GUIDANCE_RATE if steady else None,
                           threads=threads, reserve_cores=reserve_cores)
    if preview:
        if method != "student":
            raise SamplerError("a preview is the student's; it has no teacher method")
        config = replace(config, few_step=True, ctmc_every=0, use_energy=False, use_latent=False, polish=False)
    config.check()
    return config
