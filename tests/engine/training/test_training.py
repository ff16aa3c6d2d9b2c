"""Training: EMA, deterministic batches, resume == uninterrupted, DDP on gloo, every stage end
to end on fake clips, and the model bundle."""
import dataclasses
import os
import time
from pathlib import Path

import pytest
import torch
import torch.multiprocessing as mp

from engine.models.bundle import BundleError, ModelConfig, load_bundle, load_default, untrained_bundle, weights_digest
from engine.models.unet import UNetConfig
from engine.models.vqvae import VQVAEConfig
from engine.training import checkpoint
from engine.training.command import TrainError, train_command
from engine.training.config import STAGES, TrainConfig
from engine.training.ema import EMA
from engine.training.export import bundle_from_runs
from engine.training.loop import StepBatches, train
from engine.training.stages import StageUnavailable
from tests.engine.fixtures import FakeClips

torch.set_num_threads(1)
TINY_UNET = UNetConfig(channels=(16, 16, 16, 16), embed_dim=32, heads=2)
TINY_MODEL = ModelConfig(vqvae=VQVAEConfig(channels=16, codebook_size=16), teacher_unet=TINY_UNET,
                         student_unet=dataclasses.replace(TINY_UNET, n_heads_out=3))


def tiny_config(steps: int = 2) -> TrainConfig:
    return TrainConfig(steps=steps, batch_size=2, threads=1, warmup_steps=1, model=TINY_MODEL,
                       surrogate_init_latents=1, checkpoint_every_s=1e9)


def test_ema_update_warms_up_then_holds_its_decay():
    model = torch.nn.Linear(2, 1)
    ema = EMA(model, decay=0.9)
    before = ema.shadow.weight.clone()
    with torch.no_grad():
        model.weight.add_(1.0)
    ema.update(model)  # first update: decay 1/10, the average jumps most of the way
    assert torch.allclose(ema.shadow.weight, 0.1 * before + 0.9 * model.weight)
    for _ in range(200):
        ema.update(model)
    assert ema.current_decay() == 0.9
    assert torch.allclose(ema.shadow.weight, model.weight, atol=1e-6)
    assert not ema.shadow.weight.requires_grad

def test_step_batches_are_deterministic_and_split_across_ranks():
    a = list(StepBatches(10, 3, steps=5, start=0, seed=1))
    assert a == list(StepBatches(10, 3, steps=5, start=0, seed=1))
    assert list(StepBatches(10, 3, steps=5, start=2, seed=1)) == a[2:]
    r0, r1 = (list(StepBatches(10, 3, 5, 0, 1, rank=r, world=2)) for r in (0, 1))
    assert r0 != r1 and all(len(b) == 3 for b in r0 + r1)


def test_resume_equals_uninterrupted(tmp_path):
    data = FakeClips(4)
    train("vqvae", tiny_config(4), data, runs=tmp_path / "straight", progress=False)
    train("vqvae", tiny_config(2), data, runs=tmp_path / "resumed", progress=False)
    train("vqvae", tiny_config(4), data, runs=tmp_path / "resumed", resume=True, progress=False)
    a = checkpoint.load(tmp_path / "straight" / "vqvae" / "checkpoint.pt")
    b = checkpoint.load(tmp_path / "resumed" / "vqvae" / "checkpoint.pt")
    assert a["step"] == b["step"] == 4
    for key in ("model", "ema"):
        for name, value in a[key].items():
            assert torch.equal(value, b[key][name]), (key, name)


def test_time_budget_stops_early_saved_and_resume_goes_on(tmp_path):
    data = FakeClips(4)
    budget = dataclasses.replace(tiny_config(4), stage_seconds=0.0)     # over budget after the first step
    metrics = train("vqvae", budget, data, runs=tmp_path / "budget", progress=False)["vqvae"]
    assert metrics["steps"] == 1 and checkpoint.load(tmp_path / "budget" / "vqvae" / "checkpoint.pt")["step"] == 1
    assert checkpoint.load(tmp_path / "budget" / "vqvae" / "final.pt")["metrics"]["steps"] == 1
    train("vqvae", tiny_config(4), data, runs=tmp_path / "budget", resume=True, progress=False)
    train("vqvae", tiny_config(4), data, runs=tmp_path / "straight", progress=False)
    a, b = (checkpoint.load(tmp_path / run / "vqvae" / "checkpoint.pt") for run in ("budget", "straight"))
    assert a["step"] == b["step"] == 4
    assert all(torch.equal(v, b["model"][k]) for k, v in a["model"].items())


def test_warm_start_fine_tunes_from_the_stages_own_final_weights(tmp_path):
    """At learning rate 0 a warm-started run ends where the stage's final.pt began it; a fresh
    run (no warm start) begins from new weights."""
    data = FakeClips(4)
    train("encoders", tiny_config(2), data, runs=tmp_path, progress=False)
    before = checkpoint.load(tmp_path / "encoders" / "final.pt")["parts"]["conditioner"]
    still = dataclasses.replace(tiny_config(1), lr=0.0, warm_start=True, seed=5)
    train("encoders", still, data, runs=tmp_path / "x", progress=False)   # nothing to start from there
    fresh = checkpoint.load(tmp_path / "x" / "encoders" / "final.pt")["parts"]["conditioner"]
    train("encoders", still, data, runs=tmp_path, progress=False)
    after = checkpoint.load(tmp_path / "encoders" / "final.pt")["parts"]["conditioner"]
    assert all(torch.allclose(after[k].float(), v.float()) for k, v in before.items())
    assert not all(torch.allclose(fresh[k].float(), v.float()) for k, v in before.items())


def test_artist_style_training_storyboards_change_the_sketch_not_the_motion(tmp_path):
    from engine.dataset import DatasetConfig, StoryboardWindows
    from engine.synth import synthesize
    path = tmp_path / "clip.npz"
    synthesize("handoff", 0, fps=20).save(path)
    clean, drawn = (StoryboardWindows([path], DatasetConfig(artist_share=share))[0] for share in (0.0, 1.0))
    assert torch.equal(clean["joints"], drawn["joints"])
    assert not torch.equal(clean["kp2d"], drawn["kp2d"])
    assert torch.equal(StoryboardWindows([path], DatasetConfig(artist_share=1.0))[0]["kp2d"], drawn["kp2d"])


@pytest.mark.parametrize("flag", ["batch_size", "lr", "minutes"])
def test_train_command_refuses_a_non_positive_override(tmp_path, flag):
    with pytest.raises(TrainError, match="must be positive"):
        train_command("vqvae", data=[str(tmp_path)], runs=str(tmp_path), **{flag: 0})


@pytest.mark.parametrize("flag", ["artist_share", "sparse_share"])
def test_train_command_refuses_a_share_outside_0_1(tmp_path, flag):
    with pytest.raises(TrainError, match="must be between 0 and 1"):
        train_command("vqvae", data=[str(tmp_path)], runs=str(tmp_path), **{flag: 1.5})


def test_later_stage_without_prerequisite_is_a_clear_error(tmp_path):
    with pytest.raises(StageUnavailable, match="needs stage 'vqvae'"):
        train("teacher", tiny_config(), FakeClips(2), runs=tmp_path, progress=False)


def _ddp_worker(rank: int, world: int, init_file: str, runs: str):
    torch.distributed.init_process_group("gloo", init_method=f"file://{init_file}", rank=rank, world_size=world)
    try:
        # A checkpoint is due at every step on rank 0's clock (a collective save on both ranks).
        train("vqvae", dataclasses.replace(tiny_config(2), checkpoint_every_s=0.0), FakeClips(4), runs=runs,
              progress=False)
        flat = torch.cat([p.detach().flatten() for p in _trained_vqvae_params(runs)])
        gathered = [torch.zeros_like(flat) for _ in range(world)]
        torch.distributed.all_gather(gathered, flat)
        if rank == 0:
            torch.save({"same": all(torch.equal(gathered[0], g) for g in gathered)}, Path(runs) / "ddp.pt")
        # gloo's worker threads can still hold the all_gather's tensors for a moment; if the process
        # exits then, freeing them at interpreter shutdown aborts it (SIGABRT, ~1 run in 15).
        # A barrier holds no Python tensors, so the last collective's work is retired harmlessly.
        torch.distributed.barrier()
    finally:
        torch.distributed.destroy_process_group()
    # Even so, gloo's static destructors at interpreter exit can still abort ("terminate called
    # without an active exception", seen in CI): a worker whose work is done and written skips them.
    os._exit(0)


def _trained_vqvae_params(runs):
    state = checkpoint.load(Path(runs) / "vqvae" / "checkpoint.pt")["model"]
    return [v for k, v in state.items() if v.is_floating_point()]


def test_ddp_two_processes_on_gloo(tmp_path):
    init_file = tmp_path / "init"
    mp.spawn(_ddp_worker, args=(2, str(init_file), str(tmp_path)), nprocs=2, join=True)
    assert torch.load(tmp_path / "ddp.pt")["same"]
    assert (tmp_path / "vqvae" / "final.pt").exists()


def test_every_stage_end_to_end_then_bundle(tmp_path):
    results = train("all", tiny_config(2), FakeClips(4), runs=tmp_path / "runs", progress=False)
    assert list(results) == list(STAGES)
    for stage, metrics in results.items():
        assert torch.isfinite(torch.tensor(metrics["loss"])), stage
    assert results["vqvae"]["joint_error_m"] > 0
    bundle = bundle_from_runs(tmp_path / "runs", TINY_MODEL)
    assert bundle.trained and bundle.metadata["stages"] == list(STAGES)
    bundle.save(tmp_path / "bundle.pt")
    loaded = load_bundle(tmp_path / "bundle.pt")
    assert loaded.trained
    w0 = bundle.student.backbone.output.weight
    assert torch.allclose(loaded.student.backbone.output.weight, w0, atol=1e-2 * float(w0.abs().max()) + 1e-6)


def test_bundle_fallback_roundtrip_and_errors(tmp_path):
    fallback = load_default(tmp_path / "missing.pt")
    assert fallback.trained is False and "untrained" in fallback.metadata["note"]
    untrained_bundle().save(tmp_path / "b.pt")
    start = time.perf_counter()
    loaded = load_bundle(tmp_path / "b.pt")
    assert time.perf_counter() - start < 10  # ~1 s on a quiet 2-core machine
    z = torch.randn(1, 30, 3, 32)
    assert loaded.vqvae.decode(z)["joints"].shape == (1, 120, 2, 22, 3)
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(BundleError, match="not a readable model bundle"):
        load_bundle(tmp_path / "junk.pt")
    torch.save({"something": 1}, tmp_path / "other.pt")
    with pytest.raises(BundleError, match="not a Sketch2Colab model bundle"):
        load_bundle(tmp_path / "other.pt")
    data = torch.load(tmp_path / "b.pt")
    data["weights"]["student"]["backbone.output.weight"] = torch.zeros(3, 3).half()
    torch.save(data, tmp_path / "wrong.pt")
    with pytest.raises(BundleError, match="do not match their checksum"):
        load_bundle(tmp_path / "wrong.pt")
    data["weights_sha256"] = weights_digest(data["weights"])           # consistent, but the wrong shape
    torch.save(data, tmp_path / "wrong.pt")
    with pytest.raises(BundleError, match="weights of part 'student' do not fit"):
        load_bundle(tmp_path / "wrong.pt")
    with pytest.raises(ValueError):  # BundleError is a ValueError for callers that catch those
        load_default(tmp_path / "junk.pt")


def test_baseline_stages_train_on_the_models_runs_and_ship_tied_to_their_bundle(tmp_path):
    from engine.models.bundle import BASELINE_PARTS, load_baselines, save_baselines
    from engine.training.card import export_baselines
    runs = tmp_path / "runs"
    train("all", tiny_config(1), FakeClips(4), runs=runs, progress=False)
    for stage in ("sketch2anim", "controlnet1", "controlnet2"):
        metrics = train(stage, tiny_config(2), FakeClips(4), runs=runs, progress=False)[stage]
        assert torch.isfinite(torch.tensor(metrics["loss"])), stage
    bundle = bundle_from_runs(runs, TINY_MODEL)
    bundle.save(tmp_path / "bundle.pt")
    base = load_bundle(tmp_path / "bundle.pt")
    assert not base.has_part("sketch2anim")
    card = export_baselines(runs, tmp_path / "baselines.pt", [], [], base=tmp_path / "bundle.pt")
    assert card["stages"] == ["sketch2anim", "controlnet1", "controlnet2"]
    assert (tmp_path / "baselines.md").read_text().startswith("# Model card")
    both = load_baselines(base, tmp_path / "baselines.pt")
    assert all(both.has_part(name) for name in BASELINE_PARTS) and both.has_part("student")
    final = checkpoint.load(runs / "controlnet2" / "final.pt")["parts"]["controlnet_student"]
    w = both.controlnet_student.backbone.branches["kf"].hint.weight
    assert torch.allclose(w, final["backbone.branches.kf.hint.weight"], atol=1e-2 * float(w.abs().max()) + 1e-6)
    # A retrained teacher: the ablation's student (distilled from it) is left out, Sketch2Anim-INT
    # (which only shares the VQ-VAE) stays.
    changed = load_bundle(tmp_path / "bundle.pt")
    changed.metadata["part_sha256"]["teacher"] = "another"
    moved = load_baselines(changed, tmp_path / "baselines.pt")
    assert moved.has_part("sketch2anim") and not moved.has_part("controlnet_student")
    assert moved.metadata["stale_baselines"] == ["controlnet_student"]
    with pytest.raises(BundleError, match="model config differs"):
        load_baselines(untrained_bundle(), tmp_path / "baselines.pt")
    with pytest.raises(ValueError):
        save_baselines(tmp_path / "x.pt", base, {"student": base.student}, {})


def test_baseline_stage_without_its_prerequisite_is_a_clear_error(tmp_path):
    with pytest.raises(StageUnavailable, match="controlnet2. needs stage"):
        train("controlnet2", tiny_config(1), FakeClips(2), runs=tmp_path, progress=False)


def test_a_text_model_fine_tunes_from_a_sketch_only_one(tmp_path):
    """--text --warm-start: the sketch-only weights carry over, the text layers start fresh (the
    cross-attention at zero, so the first step begins at the sketch-only model)."""
    data = FakeClips(4)
    for stage in ("vqvae", "encoders", "teacher"):
        train(stage, tiny_config(1), data, runs=tmp_path, progress=False)
    before = checkpoint.load(tmp_path / "teacher" / "final.pt")["parts"]
    reading = dataclasses.replace(tiny_config(1), lr=0.0, warm_start=True, model=TINY_MODEL.with_text())
    train("teacher", reading, data, runs=tmp_path, progress=False)
    after = checkpoint.load(tmp_path / "teacher" / "final.pt")["parts"]
    assert any(k.startswith("text.") for k in after["conditioner"])
    from engine.training.export import runs_model_config
    assert runs_model_config(tmp_path).encoder.text          # what `bundle` builds from these runs
    bundled = bundle_from_runs(tmp_path)                     # the teacher's conditioner, not the encoders stage's
    assert torch.equal(bundled.conditioner.text.embed.weight, after["conditioner"]["text.embed.weight"])
    assert any(k.startswith("backbone.text_attn.") for k in after["teacher"])
    for part in ("teacher", "conditioner"):
        assert all(torch.allclose(after[part][k].float(), v.float()) for k, v in before[part].items())
    with pytest.raises(checkpoint.CheckpointError, match="weights this model lacks"):   # and not the other way
        train("teacher", dataclasses.replace(tiny_config(1), warm_start=True), data, runs=tmp_path, progress=False)
