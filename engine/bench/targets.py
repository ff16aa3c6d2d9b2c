"""The paper's headline gains of Ours over the COLLAGE Teacher, and whether a run meets them.

Relative change = (ours - teacher) / teacher; every target is a reduction (lower is better), so
a target is met when the relative change is at or below it (to within rounding, 1e-9).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

# Paper section 5: "Relative to COLLAGE Teacher, Ours cuts FID by roughly 22% ..."
PAPER_TARGETS = {"FID": -0.22, "FootSkate": -0.24, "K2D": -0.37, "K3D": -0.32, "T2D": -0.45, "T3D": -0.40,
                 "Obj": -0.45, "Anc": -0.51, "Pen": -0.21}


@dataclass
class TargetCheck:
    metric: str
    ours: float | None
    teacher: float | None
    relative: float | None              # None when either figure is missing or the teacher's is 0
    target: float
    met: bool | None                    # None when relative is None


def relative_change(ours: float | None, teacher: float | None) -> float | None:
    if ours is None or teacher is None or not (math.isfinite(ours) and math.isfinite(teacher)) or teacher == 0:
        return None
    return (ours - teacher) / abs(teacher)


def check_targets(ours: dict[str, float], teacher: dict[str, float],
                  targets: dict[str, float] = PAPER_TARGETS) -> list[TargetCheck]:
    checks = []
    for metric, target in targets.items():
        rel = relative_change(ours.get(metric), teacher.get(metric))
        checks.append(TargetCheck(metric, ours.get(metric), teacher.get(metric), rel, target,
                                  None if rel is None else rel <= target + 1e-9))
    return checks
