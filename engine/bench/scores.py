"""Per-method figures of a protocol: means of the per-sample metrics, plus FID and R-precision.

Per-sample figures are averaged over the samples that have them (fail@x means become failure
rates). FID and R-precision (top 3, batches of 32) come from engine.evaluation when an evaluator
is loaded; FID compares the method's motions with the held-out clips of the same items.
"""
from __future__ import annotations

from collections import defaultdict

import numpy as np

from .runner import SampleResult

COLUMNS = ("FID", "R-prec@3", "R-text@3", "MM Dist", "FootSkate", "K2D", "K3D", "T2D", "T3D", "MPJPE", "Pelvis", "fail@0.2",
           "fail@0.5", "Obj", "Anc", "Pen", "Pen>4cm", "ContactF1", "ECE", "Brier", "Diversity")


def mean_metrics(samples: list[SampleResult]) -> dict[str, float]:
    """Mean of each metric over the samples that report it; `n` is the sample count."""
    values: dict[str, list[float]] = defaultdict(list)
    for s in samples:
        for key, v in s.metrics.items():
            if np.isfinite(v):
                values[key].append(v)
    out = {key: float(np.mean(v)) for key, v in values.items()}
    out["n"] = len(samples)
    return out


def evaluator_metrics(evaluator, samples: list[SampleResult], references, text_embedder=None) -> dict[str, float]:
    """FID against the references (MotionClips) and storyboard -> motion R-precision top 3; where
    every storyboard has text and a text embedder is given, text -> motion R-precision top 3 and MM Dist."""
    from ..evaluation.evaluator import fid, r_precision_top3
    if evaluator is None or len(samples) < 2:
        return {}
    clips = [s.clip for s in samples]
    out = {"FID": fid(evaluator, clips, references),
           "R-prec@3": r_precision_top3(evaluator, [s.storyboard for s in samples], clips)}
    texts = [s.storyboard.text for s in samples]
    if text_embedder is not None and all(texts):
        from ..evaluation.text_motion import mm_distance, text_r_precision_top3
        out.update({"R-text@3": text_r_precision_top3(evaluator, text_embedder, texts, clips),
                    "MM Dist": mm_distance(evaluator, text_embedder, texts, clips)})
    return out


def by_method(samples: list[SampleResult], evaluator=None, references_by_item=None,
              text_embedder=None) -> dict[str, dict[str, float]]:
    """method key -> mean metrics (+ FID / R-precision when an evaluator is given, text ones too
    with a text embedder)."""
    groups: dict[str, list[SampleResult]] = defaultdict(list)
    for s in samples:
        groups[s.method].append(s)
    out = {}
    for method, group in groups.items():
        figures = mean_metrics(group)
        if evaluator is not None and references_by_item:
            figures.update(evaluator_metrics(evaluator, group, [references_by_item[s.item] for s in group],
                                             text_embedder))
        out[method] = figures
    return out


def by_key(samples: list[SampleResult], key) -> dict[tuple, dict[str, float]]:
    """(method, key(sample)) -> mean metrics, e.g. key = noise level or scenario."""
    groups: dict[tuple, list[SampleResult]] = defaultdict(list)
    for s in samples:
        groups[(s.method, key(s))].append(s)
    return {k: mean_metrics(v) for k, v in groups.items()}


def paired(samples: list[SampleResult], method: str, other: str) -> tuple[dict[str, float], dict[str, float]]:
    """Mean metrics of `method` and `other` on the items both ran (DDPM runs on a subset)."""
    items = {s.item for s in samples if s.method == other} & {s.item for s in samples if s.method == method}
    pick = lambda m: mean_metrics([s for s in samples if s.method == m and s.item in items])  # noqa: E731
    return pick(method), pick(other)
