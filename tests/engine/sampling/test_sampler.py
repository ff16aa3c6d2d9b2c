"""The guided streaming sampler on a small untrained bundle: streaming, determinism,
cancellation, variations, methods, guidance that works, and odd storyboards."""
import copy
from dataclasses import replace

import numpy as np
import pytest
import torch

from engine.metrics import adherence
from engine.models.bundle import ModelConfig, load_bundle, untrained_bundle
from engine.models.teacher import VPSchedule
from engine.request import Request
from engine.sampling.config import SamplerConfig, SamplerError, sampler_config
from engine.sampling.sampler import sample as sample_request
from engine.storyboard import Agent, Storyboard

EXAMPLE = "resources/examples/box_handoff.json"


@pytest.fixture(scope="module")
def bundle():
    torch.set_num_threads(1)
    return untrained_bundle(replace(ModelConfig.default(), schedule=VPSchedule(steps=12)))


@pytest.fixture(scope="module")
def storyboard():
    return Storyboard.load(EXAMPLE)


def sample(bundle, storyboard, config, checkpoint=lambda: None):
    """The sampler on a request built from the storyboard (raises when the first step is asked
    for, as a generator: the request is built inside it)."""
    yield from ()
    return (yield from sample_request(bundle, Request.build(storyboard, config), checkpoint))


def drain(gen):
    events = []
    try:
        while True:
            events.append(next(gen))
    except StopIteration as stop:
        return events, stop.value


def test_streams_one_event_per_step_then_the_result(bundle, storyboard):
    events, result = drain(sample(bundle, storyboard, SamplerConfig(steps=4)))
    assert [e.step for e in events] == [0, 1, 2, 3] and all(e.num_steps == 4 for e in events)
    assert [e.t for e in events] == sorted((e.t for e in events), reverse=True) and events[-1].t == 0.0
    for e in events:
        assert e.preview.joints.shape == (120, 2, 22, 3) and e.preview.obj_pose.shape == (120, 1, 7)
        assert np.allclose(e.phase.sum(-1), 1.0, atol=1e-5) and e.phase.shape == (120, 3)
        assert ("total" in e.energies) == (e.t <= SamplerConfig().guidance_start)  # guided steps report
    clip = result.clips[0]
    assert np.isfinite(clip.joints).all() and clip.contact.shape == (120, 2, 2)
    assert result.network_evals == 8 and result.first_step_s <= result.wall_time_s
    stages = result.stage_s                     # where the time went, within the wall time
    assert {"conditioning", "network", "planning", "guidance", "finishing"} <= set(stages)
    assert all(v > 0 for v in stages.values()) and sum(stages.values()) <= result.wall_time_s


def test_same_seed_same_motion_other_seed_other(bundle, storyboard):
    a = drain(sample(bundle, storyboard, SamplerConfig(steps=2, seed=3)))[1].clips[0]
    b = drain(sample(bundle, storyboard, SamplerConfig(steps=2, seed=3)))[1].clips[0]
    c = drain(sample(bundle, storyboard, SamplerConfig(steps=2, seed=4)))[1].clips[0]
    assert np.array_equal(a.joints, b.joints) and not np.allclose(a.joints, c.joints)


def test_closing_cancels_between_steps(bundle, storyboard):
    gen = sample(bundle, storyboard, SamplerConfig(steps=10))
    first = next(gen)
    gen.close()
    assert first.step == 0
    with pytest.raises(StopIteration):
        next(gen)


def test_a_checkpoint_that_raises_stops_the_finishing_after_the_last_step(bundle, storyboard):
    calls = []
    events, _ = drain(sample(bundle, storyboard, SamplerConfig(steps=2), lambda: calls.append(len(calls))))
    stages = len(calls)
    assert len(events) == 2 and stages >= 8          # before the decode, between the finishing's stages

    class Stale(Exception):
        pass

    def stale():
        if len(calls) == stages - 1:                 # the last stage is not run
            raise Stale
        calls.append(0)

    calls.clear()
    gen = sample(bundle, storyboard, SamplerConfig(steps=2), stale)
    assert [next(gen).step for _ in range(2)] == [0, 1] and not calls   # none while stepping
    with pytest.raises(Stale):
        next(gen)
    assert len(calls) == stages - 1


def test_variations_are_one_batch_of_different_samples(bundle, storyboard):
    events, result = drain(sample(bundle, storyboard, SamplerConfig(steps=2, variations=3)))
    assert events[0].latent.shape[0] == 3 and len(result.clips) == 3
    assert not np.allclose(result.clips[0].joints, result.clips[1].joints)


def test_energy_guidance_pulls_motion_towards_the_sketch(bundle, storyboard):
    """Even an untrained prior must end closer to the keyposes and paths when guided (two energy
    steps on the final latent); a capped Polyak rate pulls less, but still pulls."""
    free = drain(sample(bundle, storyboard, SamplerConfig(steps=4, use_energy=False, use_latent=False, finish=False)))[1]
    config = SamplerConfig(steps=4, finish=False, final_refine_steps=2)
    guided = drain(sample(bundle, storyboard, config))[1]
    before, after = adherence(free.clips[0], storyboard), adherence(guided.clips[0], storyboard)
    assert after["K2D"] < 0.9 * before["K2D"] and after["T2D"] < 0.9 * before["T2D"]
    capped = drain(sample(bundle, storyboard, replace(config, guidance_max_rate=5.0)))[1]
    between = adherence(capped.clips[0], storyboard)
    assert after["K2D"] < between["K2D"] < before["K2D"] and after["T2D"] < between["T2D"] < before["T2D"]


def test_the_finished_result_lands_on_the_keyposes_with_a_rigid_skeleton(bundle, storyboard):
    raw = drain(sample(bundle, storyboard, SamplerConfig(steps=2, finish=False)))[1].clips[0]
    done = drain(sample(bundle, storyboard, SamplerConfig(steps=2)))[1].clips[0]
    # The untrained fixture's bodies are shapeless; finishing still halves the keypose error.
    assert adherence(done, storyboard)["K2D"] < 0.5 * adherence(raw, storyboard)["K2D"]
    assert done.bone_offsets is not None and np.isfinite(done.joints).all()


@pytest.mark.parametrize("method,steps", [("teacher-ddim", 3), ("teacher-ddpm", 0)])
def test_teacher_methods_stream_the_same_way(bundle, storyboard, method, steps):
    events, result = drain(sample(bundle, storyboard, SamplerConfig(method=method, steps=max(steps, 1))))
    assert len(events) == (steps or 12) and np.isfinite(result.clips[0].joints).all()


ABLATIONS = {"use_ctmc": False, "use_temporal_bias": False, "trajectory_only": True, "use_energy": False,
             "use_latent": False, "finish": False, "langevin_steps": 3}


def lively(config: ModelConfig):
    """An untrained bundle whose zero-initialised layers (output heads, the attention bias) are
    randomised too, so that every input reaches the output."""
    bundle = untrained_bundle(replace(config, schedule=VPSchedule(steps=12)))
    generator = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for part in bundle.parts.values():
            for p in part.parameters():
                if p.abs().sum() == 0:
                    p.copy_(0.1 * torch.randn(p.shape, generator=generator))
    return bundle


@pytest.fixture(scope="module")
def lively_bundle():
    return lively(ModelConfig.default())


@pytest.mark.parametrize("switch", list(ABLATIONS))
def test_each_ablation_switch_changes_the_motion(lively_bundle, storyboard, switch):
    """A switch the sampler ignored would give the default's motion: every one must change it,
    and show where it acts."""
    config = SamplerConfig(steps=4, seed=1)
    base_events, base = drain(sample(lively_bundle, storyboard, config))
    events, result = drain(sample(lively_bundle, storyboard, replace(config, **{switch: ABLATIONS[switch]})))
    assert np.isfinite(result.clips[0].joints).all()
    assert np.abs(result.clips[0].joints - base.clips[0].joints).max() > 1e-4
    energies = set().union(*(e.energies for e in events))
    if switch == "use_ctmc":            # no planner: phases stay uniform, and the contact terms ungated
        assert all(np.allclose(e.phase, 1 / 3) for e in events)
        assert not all(np.allclose(e.phase, 1 / 3) for e in base_events)
    if switch == "trajectory_only":
        assert energies - {"latent", "total"} == {"trajectory"}
    if switch == "use_energy":
        assert energies == {"latent", "total"}
    if switch == "use_latent":
        assert "latent" not in energies and "keyframe" in energies
    if switch == "langevin_steps":
        assert result.network_evals == base.network_evals + 3


def test_the_texts_own_weight_moves_the_motion_only_where_there_is_a_text(storyboard):
    reader = lively(ModelConfig.default().with_text())
    config = SamplerConfig(steps=3, seed=1)
    weighted = replace(config, text_cfg=4.0)
    assert storyboard.text
    _, plain = drain(sample(reader, storyboard, config))
    _, stronger = drain(sample(reader, storyboard, weighted))
    assert stronger.network_evals == plain.network_evals          # the extra pass rides in the same batch
    assert np.abs(stronger.clips[0].joints - plain.clips[0].joints).max() > 1e-4
    silent = replace(storyboard, text="")
    _, a = drain(sample(reader, silent, config))
    _, b = drain(sample(reader, silent, weighted))
    np.testing.assert_array_equal(a.clips[0].joints, b.clips[0].joints)
    with pytest.raises(SamplerError, match="text's guidance weight"):
        sampler_config(text_cfg=-1.0)


def test_one_person_no_object_odd_length(bundle, storyboard):
    sb = replace(storyboard, length=61, agents=storyboard.agents[:1], objects=[], object_keys=[],
                 object_paths=[], contacts=[],
                 keyposes=[k for k in storyboard.keyposes if k.agent == "A" and k.frame < 61],
                 trajectories=[replace(t, end=min(t.end, 60)) for t in storyboard.trajectories
                               if t.agent == "A" and t.start < 61])
    sb.validate()
    _, result = drain(sample(bundle, sb, SamplerConfig(steps=2)))
    clip = result.clips[0]
    assert clip.joints.shape == (61, 1, 22, 3) and clip.obj_pose is None


def test_a_storyboard_at_another_frame_rate_is_animated_at_the_models(bundle, storyboard):
    """The network sees the storyboard's time at MODEL_FPS; everything handed out (previews,
    phases, the result) is at the storyboard's rate, on its frames."""
    at30 = storyboard.retimed(30.0)
    events, result = drain(sample(bundle, at30, SamplerConfig(steps=2)))
    _, at20 = drain(sample(bundle, storyboard, SamplerConfig(steps=1)))
    assert events[0].latent.shape[1] in (30, 31)               # 6 s at 20 fps (+ a frame), not 9 s
    assert events[-1].phase.shape == (at30.length, 3)
    preview = events[-1].decode()
    clip = result.clips[0]
    assert (preview.fps, preview.num_frames) == (clip.fps, clip.num_frames) == (30.0, at30.length)
    assert adherence(clip, at30)["K2D"] < adherence(at20.clips[0], storyboard)["K2D"] + 0.01


def test_requests_it_cannot_serve_fail_clearly(bundle, storyboard):
    three = replace(storyboard, agents=storyboard.agents + [Agent("C")])
    with pytest.raises(SamplerError, match="at most 2 people"):
        next(sample(bundle, three, SamplerConfig()))
    with pytest.raises(SamplerError, match="unknown method"):
        next(sample(bundle, storyboard, SamplerConfig(method="magic")))


def test_surrogate_check_reports_a_cosine_per_guided_step_and_changes_nothing(storyboard):
    routed = untrained_bundle(replace(ModelConfig.default(), schedule=VPSchedule(steps=12)))
    routed.metadata["stages"] = ["surrogate"]             # route through B_rho (random weights)
    config = SamplerConfig(steps=4, finish=False)
    plain_events, plain = drain(sample(routed, storyboard, config))
    events, checked = drain(sample(routed, storyboard, replace(config, check_surrogate=True)))
    cosines = [e.energies["surrogate_cosine"] for e in events if "total" in e.energies]
    assert len(cosines) == sum("total" in e.energies for e in plain_events) > 0
    assert all(-1.0 <= c <= 1.0 for c in cosines)
    assert np.array_equal(plain.clips[0].joints, checked.clips[0].joints)


def test_a_preview_is_the_preview_students_few_jumps_one_evaluation_each(bundle, storyboard):
    config = sampler_config(preview=True, seed=3)
    events, result = drain(sample(bundle, storyboard, config))
    jumps = bundle.config.preview_steps
    assert [e.step for e in events] == list(range(jumps)) and events[-1].t == 0.0
    assert result.network_evals == jumps                    # guidance distilled: one pass per step
    assert np.isfinite(result.clips[0].joints).all()
    # The preview student is what runs: other weights in it, other motion.
    other = copy.deepcopy(bundle)
    with torch.no_grad():
        for p in other.preview.parameters():
            p.add_(0.05)
    _, changed = drain(sample(other, storyboard, config))
    assert not np.allclose(changed.clips[0].joints, result.clips[0].joints)


def test_a_bundle_without_a_preview_student_says_so(storyboard, tmp_path):
    trained = untrained_bundle()
    trained.trained, trained.metadata = True, {"absent_parts": ["preview"]}
    trained.save(tmp_path / "old.pt")
    loaded = load_bundle(tmp_path / "old.pt")
    assert loaded.has_part("student") and not loaded.has_part("preview")
    with pytest.raises(SamplerError, match="no preview student"):
        drain(sample(loaded, storyboard, sampler_config(preview=True)))


def test_the_controlnet_ablation_integrates_its_own_student(lively_bundle, storyboard):
    from engine.models.bundle import build_parts
    config = SamplerConfig(steps=3, seed=1, student_part="controlnet_student")
    with pytest.raises(SamplerError, match="no trained 'controlnet_student'"):
        drain(sample(lively_bundle, storyboard, config))
    ablation = build_parts(lively_bundle.config, ("controlnet_student",))["controlnet_student"].eval()
    ablation.backbone.main.load_state_dict(lively_bundle.student.backbone.state_dict())   # the same main network
    with_it = replace(lively_bundle, parts={**lively_bundle.parts, "controlnet_student": ablation}, trained=True)
    _, ours = drain(sample(with_it, storyboard, replace(config, student_part="student")))
    _, result = drain(sample(with_it, storyboard, config))
    assert result.network_evals == ours.network_evals
    # its branches start at zero: the storyboard reaches it only through the guidance, not the network
    assert np.abs(result.clips[0].joints - ours.clips[0].joints).max() > 1e-4
