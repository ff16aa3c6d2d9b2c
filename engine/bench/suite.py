"""The whole benchmark in one call: protocols, methods, scores, targets, speed, diagnostics.

`run_bench(BenchConfig.full())` (about 40-60 min on 2 CPU cores) or `BenchConfig.quick()`
(under 5 min) returns one JSON-able dict that engine.bench.report renders to Markdown; the
diagnostic PNGs are written beside the report.
"""
from __future__ import annotations

import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from ..baselines.retrieval import default_index
from . import diagnostics, plots
from .animator import ANIMATOR_TARGETS, REAL_TARGETS, animator_metrics
from .protocol import REPO_ROOT, ProtocolConfig, build_protocols
from .runner import (ABLATIONS, ALL_METHODS, FEW_STEP, OURS, OURS_30, OURS_NO_TEXT, PREVIEW, RETRIEV_ADAPT,
                     SKETCH2ANIM, STEADY,
                     TEACHER_DDIM, TEACHER_DDIM_FINISHED, TEACHER_DDPM, TEACHER_DDPM_FINISHED, RunnerConfig, generate,
                     run_protocol)
from .scores import by_key, by_method, paired
from .speed import SpeedConfig, speed_table
from .targets import PAPER_TARGETS_VS_SKETCH2ANIM, check_targets, paper_ablation_drops, relative_change

NO_TEXT_NOTE = ("Sketch+text: this model bundle does not read text (trained without it), so its sketch+text "
                "rows are sketch-only generation.")


@dataclass
class BenchConfig:
    protocol: ProtocolConfig = field(default_factory=ProtocolConfig)
    runner: RunnerConfig = field(default_factory=RunnerConfig)
    speed: SpeedConfig = field(default_factory=SpeedConfig)
    methods: tuple = tuple(m for m in ALL_METHODS if m is not OURS_NO_TEXT)   # sketch-only, real, artist
    noise_methods: tuple = (OURS, PREVIEW, TEACHER_DDIM, RETRIEV_ADAPT, SKETCH2ANIM)
    text_methods: tuple = (OURS, OURS_NO_TEXT, PREVIEW, TEACHER_DDIM_FINISHED, SKETCH2ANIM, RETRIEV_ADAPT)
    speed_methods: tuple = ALL_METHODS
    scaling_methods: tuple = (OURS, TEACHER_DDIM, TEACHER_DDPM, RETRIEV_ADAPT)
    sweep_cfg: tuple[float, ...] = (1.0, 1.3, 1.6, 2.0, 2.5)     # guidance weights of the sweep
    sweep_items: int = 6
    trace_methods: tuple = (OURS, ABLATIONS[0], ABLATIONS[1])     # Ours, w/o finishing, w/o Energy
    trace_items: int = 4
    stability_methods: tuple = (OURS, STEADY)                      # stroke-nudge stability
    stability_items: int = 10
    nudge_m: float = 0.005
    fidelity_items: int = 10                                       # surrogate gradient fidelity
    speed_scene_seed: int = 7                                      # a reserved test seed (protocol.py)
    retrieval_clips: int = 60                                      # RetrievAdapt's library size

    @classmethod
    def full(cls) -> "BenchConfig":
        return cls()

    @classmethod
    def quick(cls) -> "BenchConfig":
        return cls(protocol=ProtocolConfig(per_scenario=1, noise_scenes=2, real_windows=1, artist_scenes=5),
                   runner=RunnerConfig(variations=2, diversity_items=1, ddpm_items=1),
                   speed=SpeedConfig(repeats=3, ddpm_repeats=1),
                   speed_methods=(OURS, OURS_30, PREVIEW, FEW_STEP, TEACHER_DDPM, TEACHER_DDIM, RETRIEV_ADAPT),
                   scaling_methods=(OURS, TEACHER_DDIM, RETRIEV_ADAPT),
                   sweep_cfg=(1.0, 1.6, 2.5), sweep_items=2, trace_methods=(OURS, ABLATIONS[0]), trace_items=1,
                   stability_items=5, fidelity_items=5)


def machine() -> dict:
    model = next((line.split(":", 1)[1].strip() for line in _read("/proc/cpuinfo").splitlines()
                  if line.startswith("model name")), platform.processor() or "unknown")
    return {"cpu": model, "cores": os.cpu_count(), "torch": torch.__version__, "torch_threads": torch.get_num_threads(),
            "python": platform.python_version(), "load_average": [round(x, 2) for x in os.getloadavg()]}


# What benchmark runs write: an earlier run's results are not a change to the code measured.
BENCH_OUTPUTS = ("BENCHMARKS.md", "bench.json", "bench_full", "bench_figures")


def git_revision() -> dict:
    def git(*args):
        return subprocess.run(["git", *args], cwd=REPO_ROOT, capture_output=True, text=True).stdout.strip()
    try:
        changed = git("status", "--porcelain", "--", ".", *(f":(exclude){p}" for p in BENCH_OUTPUTS))
        return {"commit": git("rev-parse", "HEAD") or "unknown", "dirty": bool(changed)}
    except OSError:
        return {"commit": "unknown", "dirty": None}


def _read(path: str) -> str:
    try:
        return Path(path).read_text()
    except OSError:
        return ""


def _progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def run_bench(bundle, config: BenchConfig, evaluator=None, figures_dir: Path | None = None,
              log=_progress, text_embedder=None) -> dict:
    """Everything the report shows, as plain data. `evaluator`: a loaded MotionEvaluator or None;
    `text_embedder`: engine.evaluation.text_motion's, for R-text@3 and MM Dist, or None."""
    started = time.perf_counter()
    notes = [] if bundle.config.encoder.text else [NO_TEXT_NOTE]
    if evaluator is None:
        notes.append("FID and R-precision: no trained evaluator (resources/evaluator.pt; train it with "
                     "`python -m engine.evaluation.train_evaluator`), shown as '-'.")
    if not getattr(bundle, "trained", True):
        notes.append("The model bundle is UNTRAINED (freshly initialised weights): quality figures only show "
                     "that the benchmark runs; speed figures are representative of the architecture.")
    missing = sorted({m.label for m in config.methods + config.text_methods + config.speed_methods
                      if not m.available(bundle)})
    if missing:
        notes.append(f"Not run: {', '.join(missing)}: no trained weights for this bundle (resources/models/baselines.pt, "
                     "made by scripts/train_baselines.sh).")
    index = None
    if any(m.sampler is None for m in config.methods + config.noise_methods + config.text_methods + config.speed_methods):
        index, library = default_index(config.protocol.data_dir, config.retrieval_clips)
        notes.append(f"RetrievAdapt library: {library}.")
    protocols = build_protocols(config.protocol)
    out: dict = {"header": {"date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "machine": machine(), "git": git_revision(),
                            "bundle": {"trained": bool(getattr(bundle, "trained", False)),
                                       "metadata": _plain(getattr(bundle, "metadata", {}))},
                            "evaluator": evaluator is not None},
                 "methods": {m.key: m.label for m in ALL_METHODS}, "notes": notes, "protocols": [], "samples": []}
    all_samples = {}
    for protocol in protocols:
        methods = {"noise": config.noise_methods, "sketch+text": config.text_methods}.get(protocol.name, config.methods)
        samples = run_protocol(bundle, protocol, methods, config.runner, index, log) if protocol.items else []
        all_samples[protocol.name] = samples
        refs = {item.id: item.reference for item in protocol.items}
        entry = {"name": protocol.name, "title": protocol.title, "notes": protocol.notes,
                 "items": len(protocol.items), "by_method": by_method(samples, evaluator, refs, text_embedder)}
        if protocol.name == "sketch+text":
            entry["by_noise"] = _nested(by_key(samples, lambda s: f"{s.noise:g}"))
        if protocol.items and protocol.name != "noise":
            entry["reference"] = _reference_figures(protocol)
        if protocol.name == "noise":
            entry["by_noise"] = _nested(by_key(samples, lambda s: f"{s.noise:g}"))
        if protocol.name == "sketch-only":
            entry["by_scenario"] = _nested(by_key(samples, lambda s: s.group))
        if protocol.name == "artist":
            entry["animator_targets"] = _animator_targets(samples, ANIMATOR_TARGETS)
        if protocol.name == "real":
            entry["animator_targets"] = _animator_targets(samples, {**ANIMATOR_TARGETS, **REAL_TARGETS})
        out["protocols"].append(entry)
        out["samples"] += [{"protocol": s.protocol, "item": s.item, "group": s.group, "noise": s.noise,
                            "method": s.method, "wall_time_s": s.wall_time_s, "network_evals": s.network_evals,
                            **s.metrics} for s in samples]
    out["targets"] = _targets(all_samples["sketch-only"], out["protocols"][0]["by_method"])
    out["speed"] = _speed(bundle, config, index, log)
    out["diagnostics"] = _diagnostics(bundle, config, protocols[0], all_samples["sketch-only"], evaluator,
                                      index, figures_dir, log)
    out["elapsed_s"] = time.perf_counter() - started
    return out


def _targets(samples, by_method_figures) -> dict:
    """Ours vs the teacher: DDPM-1000 (the paper's teacher) on the items it ran, and DDIM-50 on all;
    each with our finishing (the fair comparison: the gains of the model, not of the clean-up) and
    without (as the paper compares)."""
    out = {}
    for name, teacher_method, all_items in (("vs_ddpm_fin", TEACHER_DDPM_FINISHED, False),
                                            ("vs_ddim_fin", TEACHER_DDIM_FINISHED, True),
                                            ("vs_ddpm", TEACHER_DDPM, False), ("vs_ddim", TEACHER_DDIM, True)):
        if all_items:
            ours, teacher = by_method_figures.get(OURS.key, {}), by_method_figures.get(teacher_method.key, {})
        else:
            ours, teacher = paired(samples, OURS.key, teacher_method.key)
        out[name] = {"n": teacher.get("n", 0), "checks": [c.__dict__ for c in check_targets(ours, teacher)]}
    ours, baseline = by_method_figures.get(OURS.key, {}), by_method_figures.get(SKETCH2ANIM.key)
    if baseline:
        out["vs_sketch2anim"] = {"n": baseline.get("n", 0), "checks": [
            c.__dict__ for c in check_targets(ours, baseline, PAPER_TARGETS_VS_SKETCH2ANIM)]}
    out["ablations"] = {m.key: {metric: {"ours": relative_change(by_method_figures[m.key].get(metric), ours.get(metric)),
                                         "paper": paper}
                                for metric, paper in paper_ablation_drops().get(m.key, {}).items()}
                        for m in ABLATIONS if m.key in by_method_figures and m.key in paper_ablation_drops()}
    return out


def _reference_figures(protocol) -> dict[str, float]:
    """The animator figures of the held-out clips themselves against their storyboards (means):
    the scale the generated motion's are read against (a real swing foot pops too)."""
    from ..metrics import adherence
    rows = [{**animator_metrics(i.reference, i.storyboard, i.reference),
             "FootSkate": adherence(i.reference, i.storyboard, i.reference)["FootSkate"]} for i in protocol.items]
    return {k: float(np.nanmean([r[k] for r in rows if k in r])) for k in rows[0]}


def _animator_targets(samples, targets: dict[str, float]) -> dict:
    """method -> metric -> {"met": storyboards within the targets' bound, "n", "worst"}: every
    storyboard must meet them, so the count and the worst matter, not the mean."""
    out: dict = {}
    for s in samples:
        for metric, bound in targets.items():
            value = s.metrics.get(metric)
            if value is None or not np.isfinite(value):
                continue
            entry = out.setdefault(s.method, {}).setdefault(metric, {"met": 0, "n": 0, "worst": 0.0, "target": bound})
            entry["met"] += int(value <= bound)
            entry["n"] += 1
            entry["worst"] = max(entry["worst"], float(value))
    return out


def _speed(bundle, config: BenchConfig, index, log) -> dict:
    from ..sketchify import sketchify
    from ..synth import SCENARIOS, synthesize
    scene = synthesize(SCENARIOS[config.speed_scene_seed % len(SCENARIOS)], config.speed_scene_seed,
                       config.protocol.fps, seconds=max(config.speed.lengths_s + (6.0,)))
    by_length = {s: sketchify(scene.slice(0, int(round(s * config.protocol.fps))), config.protocol.keyframes, 0.0, 0)
                 for s in set(config.speed.lengths_s) | {6.0}}
    table = speed_table(bundle, config.speed_methods, config.scaling_methods, by_length, config.speed, index, log)
    table["scene"] = f"{scene.scenario}, seed {config.speed_scene_seed}, sliced to each length"
    table["memory"] = ("peak RSS during one more, untimed generation minus RSS before it, after malloc_trim "
                       "(/proc/self/statm sampled every 2 ms)")
    return table


def _diagnostics(bundle, config: BenchConfig, protocol, samples, evaluator, index, figures_dir, log) -> dict:
    items = protocol.items
    refs = {item.id: item.reference for item in items}
    x_key = "FID" if evaluator is not None else "K2D"
    sweep = []
    for w in config.sweep_cfg:
        part = replace(protocol, items=items[:config.sweep_items])
        runs = run_protocol(bundle, part, (OURS,), replace(config.runner, cfg=w, diversity_items=0), index)
        figures = by_method(runs, evaluator, refs).get(OURS.key, {})
        sweep.append({"cfg": w, x_key: figures.get(x_key), "ContactF1": figures.get("ContactF1")})
        log(f"sweep cfg {w:g}: {x_key} {figures.get(x_key)} contact F1 {figures.get('ContactF1')}")
    curves = {m: diagnostics.reliability([s for s in samples if s.method == m], refs)
              for m in (OURS.key, TEACHER_DDIM.key)}
    curvature, alignment = {}, {}
    for m in config.trace_methods:
        curv, align = [], []
        for item in items[:config.trace_items]:
            trace = generate(bundle, m, item.storyboard, config.runner.seed, trace=True).trace
            curv.append(diagnostics.flow_curvature(trace))
            align.append(diagnostics.energy_alignment(bundle, item.storyboard, trace))
        curvature[m.label], alignment[m.label] = diagnostics.mean_series(curv), diagnostics.mean_series(align)
        log(f"traced {m.label}")
    stability = {}
    for m in config.stability_methods:
        change = []
        for item in items[:config.stability_items]:
            moved = diagnostics.nudged(item.storyboard, config.nudge_m)
            if moved is not None:
                runs = [generate(bundle, m, board, config.runner.seed).clips[0] for board in (item.storyboard, moved)]
                change.append(diagnostics.motion_change(*runs))
        if change:
            stability[m.label] = {"n": len(change), "mean": float(np.mean([c[0] for c in change])),
                                  "median": float(np.median([c[0] for c in change])),
                                  "max": float(np.max([c[1] for c in change]))}
        log(f"nudged {m.label}")
    checked = replace(OURS, sampler=replace(OURS.sampler, check_surrogate=True))
    cosines = [energies["surrogate_cosine"] for item in items[:config.fidelity_items]
               for _, _, energies in generate(bundle, checked, item.storyboard, config.runner.seed, trace=True).trace
               if "surrogate_cosine" in energies]
    fidelity = ({"storyboards": min(config.fidelity_items, len(items)), "steps": len(cosines),
                 "mean": float(np.mean(cosines)), "median": float(np.median(cosines)), "min": float(np.min(cosines))}
                if cosines else {})
    log("checked the surrogate's gradients")
    out = {"sweep_x": x_key, "sweep": sweep, "reliability": curves, "curvature": curvature,
           "alignment": alignment, "stability": stability, "nudge_m": config.nudge_m,
           "surrogate_fidelity": fidelity, "figures": {}}
    if figures_dir is not None:
        figures_dir.mkdir(parents=True, exist_ok=True)
        labels = {OURS.key: OURS.label, TEACHER_DDIM.key: TEACHER_DDIM.label}
        made = {
            "guidance_sweep": plots.guidance_sweep(sweep, x_key, figures_dir / "guidance_sweep.png"),
            "reliability": plots.reliability_diagram({labels[k]: v for k, v in curves.items()},
                                                     figures_dir / "contact_reliability.png"),
            "curvature": plots.solver_series(curvature, "RMS(v_k - v_{k-1})", "Flow curvature over solver time",
                                             figures_dir / "flow_curvature.png"),
            "alignment": plots.solver_series(alignment, "cos(step, -grad E)", "Energy-flow alignment",
                                             figures_dir / "energy_alignment.png")}
        out["figures"] = {k: str(v) for k, v in made.items()}
    return out


def _nested(table: dict[tuple, dict]) -> dict:
    out: dict = {}
    for (method, key), figures in table.items():
        out.setdefault(method, {})[key] = figures
    return out


def _plain(value):
    """Metadata reduced to JSON-able values."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value if isinstance(value, (str, int, float, bool, type(None))) else str(value)
