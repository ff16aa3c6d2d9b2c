"""The benchmark end to end on a tiny run (2 storyboards, 2 methods, 2 solver steps, a small
untrained bundle), and the paper-target arithmetic on hand-made numbers."""
import json
import math
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from engine.artist_sketch import HARSH, ArtistConfig
from engine.bench.command import command_line
from engine.bench.diagnostics import nudged
from engine.bench.protocol import ProtocolConfig, build_protocols
from engine.bench.report import render, write
from engine.bench.runner import OURS, SKETCH2ANIM, TEACHER_DDIM, RunnerConfig
from engine.bench.speed import SpeedConfig
from engine.bench.suite import BenchConfig, run_bench
from engine.bench.targets import PAPER_TARGETS, check_targets, relative_change
from engine.demo import EXAMPLES
from engine.models.bundle import ModelConfig, untrained_bundle
from engine.models.teacher import VPSchedule
from engine.storyboard import Storyboard
from engine.synth import synthesize


def _few_steps(method):
    return replace(method, sampler=replace(method.sampler, steps=2))


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("bench")
    data = root / "data"
    (data / "salsa").mkdir(parents=True)
    # Stands in for the held-out salsa take: 2 people, 140 frames (one 120-frame window after the trim).
    real = synthesize("handshake", 3, seconds=7.0)
    replace(real, obj_pose=None, obj_anchors=None, obj_type=None, obj_size=None, phase=None,
            contact=None).save(data / "salsa" / "60_10_61_10.npz")
    bundle = untrained_bundle(replace(ModelConfig.default(), schedule=VPSchedule(steps=4)))
    methods = (_few_steps(OURS), _few_steps(TEACHER_DDIM), SKETCH2ANIM)   # the bundle has no baselines: left out
    config = BenchConfig(
        protocol=ProtocolConfig(scenarios=("carry_together", "handoff"), per_scenario=1, noise_scenes=1,
                                artist_scenes=1, noise_levels=(0.4,), text_noise=(0.0, 0.6), real_windows=1,
                                data_dir=data, shared_dir=root / "none"),
        runner=RunnerConfig(variations=2, diversity_items=1, ddpm_items=0),
        speed=SpeedConfig(repeats=1, ddpm_repeats=1, lengths_s=(2.0, 6.0)),
        methods=methods, noise_methods=methods[:1], text_methods=methods[:1], speed_methods=methods,
        scaling_methods=methods[:1],
        sweep_cfg=(1.0, 2.0), sweep_items=1, trace_methods=methods[:1], trace_items=1,
        stability_methods=methods[:1], stability_items=1, fidelity_items=1)
    results = run_bench(bundle, config, None, root / "figures", log=lambda m: None)
    md, js = root / "BENCHMARKS.md", root / "bench.json"
    write(results, command_line(True, str(md), str(js), None), md, js)
    return results, md.read_text(), json.loads(js.read_text()), root


def test_protocols_without_data_synthesize_reserved_seeds_and_skip_absent_real(tmp_path):
    protocols = build_protocols(ProtocolConfig(scenarios=("let_go",), per_scenario=1, noise_scenes=1,
                                               artist_scenes=1, noise_levels=(0.2, 0.8), data_dir=tmp_path,
                                               shared_dir=tmp_path))
    sketch, noise, real, artist, text = protocols
    assert [i.group for i in artist.items] == ["drawn", "posed"]
    assert [i.id for i in sketch.items] == ["let_go/000001"] and sketch.items[0].noise == 0.0
    assert "reserved test seeds" in sketch.notes[0]
    assert [i.noise for i in noise.items] == [0.2, 0.8]
    # same sketch seed: the same keyframes at every noise level
    frames = [[k.frame for k in item.storyboard.keyposes] for item in noise.items]
    assert frames[0] == frames[1]
    assert real.items == [] and "skipped" in real.notes[0]
    assert [i.noise for i in text.items] == [0.0, 0.6] and text.items[0].storyboard.text
    assert text.items[0].storyboard.text == text.items[1].storyboard.text        # one caption per scene


def test_another_drawing_draws_the_same_artist_scenes_otherwise(tmp_path):
    def artist(drawing):
        config = ProtocolConfig(scenarios=("let_go",), per_scenario=1, noise_scenes=0, artist_scenes=1,
                                data_dir=tmp_path, shared_dir=tmp_path, drawing=drawing)
        return next(p for p in build_protocols(config) if p.name == "artist").items
    first, again, other = artist(0), artist(0), artist(7)
    assert [i.id for i in first] == [i.id for i in other]
    for a, b, c in zip(first, again, other):
        assert a.reference is c.reference or np.array_equal(a.reference.joints, c.reference.joints)
        assert np.array_equal(a.storyboard.keyposes[0].points, b.storyboard.keyposes[0].points)
        assert not np.array_equal(a.storyboard.keyposes[0].points, c.storyboard.keyposes[0].points)


def test_a_harsher_drawing_draws_its_strokes_with_fewer_points(tmp_path):
    def strokes(artist):
        config = ProtocolConfig(scenarios=("let_go",), per_scenario=1, noise_scenes=0, artist_scenes=3,
                                data_dir=tmp_path, shared_dir=tmp_path, artist=artist)
        items = next(p for p in build_protocols(config) if p.name == "artist").items
        return [len(t.points) for i in items for t in i.storyboard.trajectories]
    plain, harsh = strokes(ArtistConfig()), strokes(HARSH)
    assert max(harsh) <= HARSH.stroke_points[1] < max(plain) and np.mean(harsh) < np.mean(plain)


def test_markdown_has_every_table_and_the_command(tiny_run):
    _, md, _, root = tiny_run
    assert f"`sketch2colab bench --quick -o {root / 'BENCHMARKS.md'} --json {root / 'bench.json'}`" in md
    for heading in ("## Held-out synthesized scenes", "## Noise robustness", "## Held-out real pairs",
                    "## Drawn the way artists draw", "What an animator looks at", "keepable-motion bounds",
                    "### Ours against the paper's targets", "## Speed", "## Diagnostics", "## Sketch + text",
                    "does not read text", "Per noise level:"):
        assert heading in md
    assert "| Ours | 2 |" in md and "| COLLAGE Teacher (DDIM-50) | 2 |" in md
    assert "Not run: Sketch2Anim-INT (DDIM-50) + finishing: no trained weights" in md
    assert "The held-out clips themselves (the motion that was sketched), by the same measures: Pop " in md
    assert "| Sketch2Anim-INT" not in md
    assert "Wall time (s) vs clip length" in md and "2 people + 1 object" in md
    assert "Stroke-nudge stability" in md and "| mean change | median change | max change |" in md
    for name in ("guidance_sweep", "contact_reliability", "flow_curvature", "energy_alignment"):
        assert (root / "figures" / f"{name}.png").stat().st_size > 1000


def test_json_figures_are_finite(tiny_run):
    _, _, data, _ = tiny_run
    sketch = data["protocols"][0]["by_method"]
    for method in ("ours", "teacher_ddim"):
        figures = sketch[method]
        for key in ("K2D", "K3D", "T2D", "T3D", "fail@0.2", "fail@0.5", "Obj", "Anc", "Pen", "Pen>4cm",
                    "FootSkate", "ContactF1", "ECE", "Brier", "Diversity"):
            assert math.isfinite(figures[key]), (method, key)
        assert figures["n"] == 2 and "FID" not in figures
    real = data["protocols"][2]["by_method"]["ours"]
    assert real["n"] == 1 and "Obj" not in real and "ContactF1" not in real
    assert 0 < real["Pelvis"] < 10 and 0 < real["MPJPE"] < 10                # both measured, in metres
    bounds = data["protocols"][2]["animator_targets"]["ours"]               # issue 18's real-motion bounds
    assert bounds["Pelvis"]["target"] == 0.15 and bounds["MPJPE"]["n"] == 1
    speed = data["speed"]["per_method"]
    assert speed["ours"]["network_evals"] == 4 and speed["teacher_ddim"]["network_evals"] == 2
    assert all(math.isfinite(speed[m]["wall_s"]) and speed[m]["wall_s"] > 0 for m in speed)
    assert set(data["speed"]["length"]["ours"]) == {"2", "6"}
    assert data["diagnostics"]["sweep_x"] == "K2D" and len(data["diagnostics"]["sweep"]) == 2
    stability = data["diagnostics"]["stability"]
    assert set(stability) == {"Ours"}
    assert stability["Ours"]["n"] == 1 and 0 <= stability["Ours"]["mean"] <= stability["Ours"]["max"] < 10
    assert data["diagnostics"]["surrogate_fidelity"] == {}   # an untrained B_rho is never routed through
    checks = {c["metric"]: c for c in data["targets"]["vs_ddim"]["checks"]}
    assert checks["FID"]["relative"] is None and checks["K2D"]["relative"] is not None
    assert data["targets"]["vs_ddpm"]["n"] == 0


def test_relative_change_and_targets_on_hand_made_numbers():
    assert relative_change(0.78, 1.0) == pytest.approx(-0.22)
    assert relative_change(1.0, 0.0) is None and relative_change(None, 1.0) is None
    assert relative_change(float("nan"), 1.0) is None
    ours = {"FID": 0.78, "FootSkate": 0.80, "K2D": 0.60, "T2D": 0.50}
    teacher = {"FID": 1.0, "FootSkate": 1.0, "K2D": 1.0, "T2D": 1.0, "K3D": 2.0}
    checks = {c.metric: c for c in check_targets(ours, teacher)}
    assert set(checks) == set(PAPER_TARGETS)
    assert checks["FID"].met is True                       # -22% exactly meets -22%
    assert checks["FootSkate"].met is False                # -20% misses -24%
    assert checks["K2D"].met is True and checks["K2D"].relative == pytest.approx(-0.40)
    assert checks["T2D"].met is True
    assert checks["K3D"].relative is None and checks["K3D"].met is None   # Ours lacks it


def test_render_marks_missing_figures_with_a_dash(tiny_run):
    results, _, _, _ = tiny_run
    md = render(results, "sketch2colab bench")
    row = next(line for line in md.splitlines() if line.startswith("| Ours | 2 |"))
    assert row.split("|")[3].strip() == "-"              # FID without an evaluator


def test_a_nudge_moves_one_stroke_point_and_nothing_else():
    board = Storyboard.load(EXAMPLES / "box_handoff.json")
    moved = nudged(board, 0.005)
    first, before = moved.trajectories[0].points, board.trajectories[0].points
    assert np.count_nonzero(first != before) == 1 and (first - before).sum() == pytest.approx(0.005)
    assert all(a is b for a, b in zip(moved.trajectories[1:], board.trajectories[1:]))
    assert nudged(replace(board, trajectories=[]), 0.005) is None


def test_speed_repeats_take_turns_across_methods(monkeypatch):
    """A burst of load from another tenant should slow one round of every method, not every run
    of one: round r runs each method once (DDPM-1000 only in its own, fewer rounds)."""
    import engine.bench.speed as speed
    from engine.bench.runner import TEACHER_DDPM
    order, walls = [], iter(range(1, 100))

    def fake_run(bundle, method, storyboard, seed, index=None):
        order.append((method.key, seed))
        return {"wall_s": float(next(walls)), "first_step_s": 0.0, "peak_rss_mib": 0.0, "network_evals": 1}

    monkeypatch.setattr(speed, "_timed_run", fake_run)
    monkeypatch.setattr(speed, "generate", lambda *a, **k: None)          # the warm-up
    sb = Storyboard()
    table = speed.speed_table(None, (OURS, TEACHER_DDPM, TEACHER_DDIM), (), {6.0: sb},
                              SpeedConfig(repeats=3, ddpm_repeats=1, busy_repeats=0))
    assert order == [("ours", 0), ("teacher_ddpm", 0), ("teacher_ddim", 0),
                     ("ours", 1), ("teacher_ddim", 1), ("ours", 2), ("teacher_ddim", 2)]
    assert table["per_method"]["ours"]["wall_s"] == 4.0 and table["per_method"]["ours"]["repeats"] == 3
    assert table["per_method"]["teacher_ddpm"]["repeats"] == 1
    assert all(isinstance(f["peak_rss_mib"], float) for f in table["per_method"].values())


def test_timed_runs_go_without_the_memory_sampler(monkeypatch):
    """The RSS sampling thread wakes for the GIL every 2 ms and slows short runs: the timed run
    starts no thread, the memory run one."""
    import threading
    import engine.bench.speed as speed
    threads = []
    monkeypatch.setattr(speed, "generate", lambda *a, **k: threads.append(threading.active_count())
                        or SimpleNamespace(first_step_s=0.0, network_evals=1, stage_s={}))
    before = threading.active_count()
    speed._timed_run(None, OURS, Storyboard(), 0)
    speed.peak_memory_mib(None, OURS, Storyboard())
    assert threads == [before, before + 1]


def test_busy_row_runs_in_turns_beside_a_real_busy_loop(monkeypatch):
    """The busy row alternates quiet and busy runs, and during the busy ones another process
    really keeps a core busy (measured by engine.cpu, as the sampler sees it)."""
    import engine.bench.speed as speed
    from engine.cpu import CpuLoad
    seen = []

    def fake_run(bundle, method, storyboard, seed, index=None):
        load = CpuLoad()
        time.sleep(0.2)
        seen.append(load.others())
        return {"wall_s": 1.0 + len(seen) % 2, "first_step_s": 0.0, "peak_rss_mib": 0.0, "network_evals": 1}

    monkeypatch.setattr(speed, "_timed_run", fake_run)
    busy = speed.beside_busy_process(None, OURS, Storyboard(), SpeedConfig(busy_repeats=2))
    quiet_load, busy_load = seen[0::2], seen[1::2]
    assert min(busy_load) > 0.7 and min(busy_load) > max(quiet_load) + 0.5
    assert busy["quiet"]["wall_s"] == 2.0 and busy["busy"]["wall_s"] == 1.0 and busy["ratio"] == 0.5 and busy["met"]
