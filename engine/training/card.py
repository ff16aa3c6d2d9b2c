"""Ship a trained bundle: collect the stages under runs/, measure it on held-out clips, and write
the weights with their model card (resources/models/default.pt + default.md); and the
benchmark's trained baselines beside it (baselines.pt + baselines.md, `export_baselines`).

The held-out figures are the model issue's acceptance checks: VQ-VAE reconstruction (mean joint
error in metres), CTMC phase accuracy and contact timing against the synthesizer's labels, and
the Jacobian surrogate's gradient cosine to exact autograd through the decoder.
"""
from __future__ import annotations

import platform
import subprocess
import time
from pathlib import Path

import torch

from ..atomic import write_text
from ..dataset import DatasetConfig, StoryboardWindows, split_files
from ..models.bundle import (BASELINE_PARTS, DEFAULT_PATH, ModelBundle, build_parts, load_baselines, load_bundle,
                             save_baselines)
from ..models.ctmc import contact_timing_error, phase_accuracy
from ..models.surrogate import gradient_cosine, random_cotangents
from . import checkpoint
from .config import BASELINE_STAGE_PARTS, BASELINE_STAGES, CONFIGS, STAGES
from .export import bundle_from_runs
from .stages import sample_batch


def held_out_files(data: list[str], real: list[str]) -> dict[str, list[Path]]:
    """Test-split files by source: {'synthesized': [...], 'real': [...]} (empty lists allowed)."""
    return {"synthesized": [f for d in data for f in split_files(synth_dir=d).test],
            "real": [f for d in real for f in split_files(real_dir=d).test]}


@torch.no_grad()
def evaluate_bundle(bundle: ModelBundle, files: list[Path], windows: int = 64, seed: int = 0) -> dict[str, float]:
    """Held-out figures on up to `windows` exact-storyboard windows of `files`."""
    if not files:
        return {}
    data = StoryboardWindows(files, DatasetConfig(noise_range=(0.0, 0.0), random_yaw=False, seed=seed))
    batch = sample_batch(data, windows)
    vq = bundle.vqvae
    z = vq.encode(batch)
    decoded = vq.decode(z)
    valid = batch["valid"][:, :, None, None]
    err = (decoded["joints"] - batch["joints"]).norm(dim=-1) * valid
    out = {"windows": int(z.shape[0]),
           "recon_joint_error_m": float(err.sum() / (valid.sum() * err.shape[2] * err.shape[3]))}
    if batch["has_labels"].sum() > 0:
        plan = bundle.planner(z, decoded, batch["contact"])
        out["phase_accuracy"] = phase_accuracy(plan.occupancy, batch["phase"], batch["has_labels"])
        out["contact_timing_error_frames"] = contact_timing_error(plan.occupancy, batch["phase"], batch["has_labels"])
    if "surrogate" in bundle.metadata.get("stages", ()):
        # Every window: one sample's cosine varies by +-0.06, so 8 windows left the mean +-0.02.
        cot = random_cotangents(z.shape[0], frames=bundle.surrogate.cfg.frames,
                                generator=torch.Generator().manual_seed(seed))
        with torch.enable_grad():
            out["surrogate_cosine"] = float(gradient_cosine(bundle.surrogate, vq.decode, z, cot).mean())
    return out


def export_default(runs: str | Path, output: str | Path, data: list[str], real: list[str],
                   config: str = "default", command: str = "") -> dict:
    """Bundle runs/ into `output`, measure it on the held-out splits, write the model card."""
    cfg = CONFIGS[config]()
    bundle = bundle_from_runs(runs)
    output = Path(output)
    bundle.metadata.update(commit=_git("rev-parse", "HEAD"), dirty=bool(_git("status", "--porcelain")),
                           training_data={"synthesized": data, "real": real}, seed=cfg.seed, config=config)
    bundle.save(output)
    started = time.perf_counter()
    loaded = load_bundle(output)
    load_s = time.perf_counter() - started
    held = held_out_files(data, real)
    figures = {name: evaluate_bundle(loaded, files) for name, files in held.items()}
    card = {"bundle": output.name, "size_mb": round(output.stat().st_size / 1e6, 2), "load_s": round(load_s, 3),
            "stages": bundle.metadata.get("stages", []), "trained": bundle.trained,
            "metrics": bundle.metadata.get("metrics", {}), "held_out": figures,
            "held_out_files": {k: [p.name for p in v] for k, v in held.items()}}
    write_text(output.with_suffix(".md"), _card_markdown(card, bundle.metadata, command))
    return card


def export_baselines(runs: str | Path, output: str | Path, data: list[str], real: list[str],
                     base: str | Path | None = None, command: str = "") -> dict:
    """The baseline stages' final weights under runs/ (later stages win), tied to the bundle they
    were trained with (`base`, default the shipped one), and their model card."""
    bundle = load_bundle(base or DEFAULT_PATH)
    parts, done, metrics = {}, [], {}
    for stage in BASELINE_STAGES:
        path = Path(runs) / stage / "final.pt"
        if not path.exists():
            continue
        final = checkpoint.load(path)
        for name in BASELINE_STAGE_PARTS[stage]:
            parts[name] = build_parts(bundle.config, (name,))[name]
            parts[name].load_state_dict(final["parts"][name])
        done.append(stage)
        metrics[stage] = final.get("metrics", {})
    if not parts:
        raise FileNotFoundError(f"{runs}: no baseline stage trained ({', '.join(BASELINE_STAGES)})")
    output = Path(output)
    meta = {"stages": done, "metrics": metrics, "commit": _git("rev-parse", "HEAD"),
            "dirty": bool(_git("status", "--porcelain")), "training_data": {"synthesized": data, "real": real}}
    save_baselines(output, bundle, parts, meta)
    load_baselines(bundle, output)      # it reads back, tied to its bundle
    card = {"file": output.name, "size_mb": round(output.stat().st_size / 1e6, 2), "stages": done,
            "parts": sorted(parts), "metrics": metrics}
    rows = [f"| {stage} | {m.get('steps', '?')} | {m.get('wall_time_s', '?')} | "
            + ", ".join(f"{k} {v:.4g}" for k, v in m.items() if k not in ("stage", "steps", "wall_time_s")
                        and isinstance(v, (int, float))) + " |" for stage, m in metrics.items()]
    write_text(output.with_suffix(".md"), "\n".join([
        "# Model card: the benchmark's trained baselines",
        "",
        f"`{output.name}`: {card['size_mb']} MB (half precision): {', '.join(card['parts'])}. Not part of the product: "
        "`sketch2colab bench` lays them over the bundle they were trained with (`load_baselines` leaves out a "
        "baseline whose bundle parts changed since: each records their weights' SHA-256)."
        + "".join(f" Not in it yet: {name} (its stages have no final weights under {Path(runs)})."
                  for name in BASELINE_PARTS if name not in parts),
        "",
        "- sketch2anim: Sketch2Anim-INT (engine/models/sketch2anim.py, engine/baselines/sketch2anim.py).",
        "- controlnet_student: the parallel-ControlNets ablation's student (engine/models/controlnet.py), "
        "trained with ours' objectives and budgets (controlnet1 = student1's, controlnet2 = student2's).",
        "",
        "```", command or "(command not recorded)", "```", "",
        f"- commit: `{meta['commit']}`{' (with uncommitted changes)' if meta['dirty'] else ''}; seed 0; "
        f"data: synthesized {data}, real {real} (train splits only)",
        "- real capture credit: the data used in this project was obtained from mocap.cs.cmu.edu. "
        "The database was created with funding from NSF EIA-0196217.",
        "",
        "| stage | steps | wall time (s) | final losses |", "|---|---|---|---|", *rows, ""]))
    return card


def _card_markdown(card: dict, meta: dict, command: str) -> str:
    stage_rows = []
    for stage in STAGES:
        m = card["metrics"].get(stage)
        if m is None:
            stage_rows.append(f"| {stage} | not trained | | |")
            continue
        losses = ", ".join(f"{k} {v:.4g}" for k, v in m.items()
                           if k not in ("stage", "steps", "wall_time_s") and isinstance(v, (int, float)))
        stage_rows.append(f"| {stage} | {m.get('steps', '?')} | {m.get('wall_time_s', 'not recorded')} | {losses} |")
    held = []
    for source, figures in card["held_out"].items():
        for k, v in figures.items():
            held.append(f"| {source} | {k} | {v:.4g} |" if isinstance(v, float) else f"| {source} | {k} | {v} |")
    return "\n".join([
        "# Model card: Sketch2Colab default bundle",
        "",
        f"`{card['bundle']}`: {card['size_mb']} MB (half precision), loads in {card['load_s']} s "
        f"on {platform.processor() or platform.machine()} ({torch.get_num_threads()} threads). "
        f"Trained: {'all stages' if card['trained'] else 'partially: ' + ', '.join(card['stages'])}.",
        "",
        "## How it was made",
        "",
        "```",
        command or "(command not recorded)",
        "```",
        "",
        f"- commit: `{meta.get('commit')}`{' (with uncommitted changes)' if meta.get('dirty') else ''}",
        f"- config: `{meta.get('config')}`, seed {meta.get('seed')}",
        f"- data: synthesized {meta.get('training_data', {}).get('synthesized')}, "
        f"real {meta.get('training_data', {}).get('real')} (train splits only; see engine/dataset.py)",
        "- real capture credit: the data used in this project was obtained from mocap.cs.cmu.edu. "
        "The database was created with funding from NSF EIA-0196217.",
        "",
        "## Stages (final EMA weights; losses are the last training batch's)",
        "",
        "| stage | steps | wall time (s) | final losses |",
        "|---|---|---|---|",
        *stage_rows,
        "",
        "## Held-out figures (test splits, measured at export)",
        "",
        "| source | figure | value |",
        "|---|---|---|",
        *held,
        "",
        "Held-out files: " + "; ".join(f"{source}: {len(names)} ({', '.join(names[:3])}{', ...' if len(names) > 3 else ''})"
                                       for source, names in card["held_out_files"].items()),
        "",
    ])


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""
