"""Diagnostic figures (matplotlib, Agg backend): one PNG per diagnostic, from the series that
engine.bench.diagnostics computes. Each function takes plain lists and a path, returns the path."""
from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the headless backend)

from ..atomic import write_bytes


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=110, format="png")
    write_bytes(path, buffer.getvalue())
    plt.close(fig)
    return path


def guidance_sweep(points: list[dict], x_key: str, path: Path) -> Path:
    """points: [{"cfg": w, x_key: value, "ContactF1": value}] -> contact F1 against x_key."""
    fig, ax = plt.subplots(figsize=(5, 4))
    xs, ys = [p.get(x_key) for p in points], [p.get("ContactF1") for p in points]
    ax.plot(xs, ys, "o-")
    for p, x, y in zip(points, xs, ys):
        ax.annotate(f"w={p['cfg']:g}", (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xlabel(x_key + (" (lower is better)" if x_key != "ContactF1" else ""))
    ax.set_ylabel("contact F1 (higher is better)")
    ax.set_title("Guidance scale sweep (Ours)")
    return _save(fig, path)


def reliability_diagram(curves: dict[str, dict[str, list[float]]], path: Path) -> Path:
    """curves: method label -> {"confidence", "frequency"} per bin."""
    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    ax.plot([0, 1], [0, 1], "k--", lw=1, label="calibrated")
    for label, c in curves.items():
        if c["confidence"]:
            ax.plot(c["confidence"], c["frequency"], "o-", label=label)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("predicted contact probability")
    ax.set_ylabel("labelled contact frequency")
    ax.set_title("Contact-timing reliability")
    ax.legend(fontsize=8)
    return _save(fig, path)


def solver_series(series: dict[str, list[tuple[float, float]]], ylabel: str, title: str, path: Path) -> Path:
    """series: method label -> [(solver time t, value)], drawn from t = 1 (noise) to 0 (data)."""
    fig, ax = plt.subplots(figsize=(5.5, 4))
    drawn = [label for label, points in series.items() if points]
    for label in drawn:
        ax.plot([p[0] for p in series[label]], [p[1] for p in series[label]], "o-", ms=3, label=label)
    ax.invert_xaxis()
    ax.set_xlabel("solver time t (1 = noise, 0 = data)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if drawn:
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "too few solver steps", ha="center", transform=ax.transAxes)
    return _save(fig, path)
