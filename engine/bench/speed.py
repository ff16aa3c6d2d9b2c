"""Speed of every method, measured in one process on one machine in one run.

Per method: median wall time per generation over `repeats` runs of a 6 s two-person-and-object
storyboard, time to the first streamed step, network evaluations, and peak memory: the peak
resident set size (RSS, /proc/self/statm sampled every 2 ms in a thread) during one more
generation minus the RSS just before it, after glibc's malloc_trim has handed freed heap back to
the OS (otherwise memory kept from an earlier run hides this one's). A working-set estimate, not
an exact allocation count. The timed runs go without the sampling thread: waking for the GIL
every 2 ms, it slowed the preview's many small numpy calls by 9% (0.146 against 0.134 s). One
untimed warm-up generation first pays the one-time costs (thread pools, lazy initialisation) so
that they land on no method. The repeats take turns across methods (round r runs every method
once), so that a burst of load from another tenant of a shared host slows one round of every
method, which the medians drop, rather than every run of whichever method it coincides with.
Scaling: wall time at clip lengths 2, 6 and 12 s and for 2 people without vs with the object.
Busy machine: the first method (Ours) again, in turns with and without a CPU-bound process beside
it (a busy loop the benchmark starts and stops itself), to show that the thread count follows the
free cores (engine.cpu); the target is at most twice the quiet time.
"""
from __future__ import annotations

import ctypes
import os
import statistics
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, replace

from ..storyboard import Storyboard
from .runner import Method, generate

PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096
LENGTHS_S = (2.0, 6.0, 12.0)


@dataclass
class SpeedConfig:
    repeats: int = 3
    ddpm_repeats: int = 3               # DDPM-1000 takes ~30x longer than the others
    scaling_repeats: int = 1
    lengths_s: tuple[float, ...] = LENGTHS_S
    busy_repeats: int = 3               # runs of the first method with and without a busy loop beside it
    busy_target: float = 2.0            # at most this many times the quiet wall time


def _trim_heap() -> None:
    """Return freed heap pages to the OS (glibc only; a no-op elsewhere)."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _rss_bytes() -> int:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * PAGE
    except OSError:
        return 0


class PeakRss:
    """Context manager: .peak_delta is the peak RSS during the block minus the RSS before it (bytes)."""

    def __enter__(self) -> "PeakRss":
        _trim_heap()
        self.before = self.peak = _rss_bytes()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()
        return self

    def _watch(self) -> None:
        while not self._stop.wait(0.002):
            self.peak = max(self.peak, _rss_bytes())

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, _rss_bytes())
        self.peak_delta = self.peak - self.before


class CompetingLoad:
    """A CPU-bound program beside the benchmark while the block runs: a busy loop on one core."""

    def __enter__(self) -> "CompetingLoad":
        self._process = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        time.sleep(0.3)  # running at full speed before the measurement starts
        return self

    def __exit__(self, *exc) -> None:
        self._process.kill()
        self._process.wait()


def _timed_run(bundle, method: Method, storyboard: Storyboard, seed: int, index=None) -> dict[str, float]:
    """One generation: wall time, first-step time (s), network evaluations, seconds per stage."""
    start = time.perf_counter()
    g = generate(bundle, method, storyboard, seed=seed, index=index)
    wall = time.perf_counter() - start
    return {"wall_s": wall, "first_step_s": g.first_step_s, "network_evals": g.network_evals, "stage_s": g.stage_s}


def peak_memory_mib(bundle, method: Method, storyboard: Storyboard, index=None) -> float:
    """The peak RSS delta (MiB) of one generation (PeakRss), untimed."""
    with PeakRss() as rss:
        generate(bundle, method, storyboard, index=index)
    return rss.peak_delta / 2 ** 20


def _medians(runs: list[dict[str, float]]) -> dict[str, float]:
    """Median wall time, first-step time and time per sampler stage of runs of one method; its
    evaluations."""
    stages = runs[-1].get("stage_s", {})
    return {"wall_s": statistics.median(r["wall_s"] for r in runs),
            "first_step_s": statistics.median(r["first_step_s"] for r in runs),
            "network_evals": runs[-1]["network_evals"], "repeats": len(runs),
            "stage_s": {k: statistics.median(r.get("stage_s", {}).get(k, 0.0) for r in runs) for k in stages}}


def measure(bundle, method: Method, storyboard: Storyboard, repeats: int, index=None) -> dict[str, float]:
    """_medians of `repeats` runs of one method in a row (seeds 0, 1, ...)."""
    return _medians([_timed_run(bundle, method, storyboard, r, index) for r in range(repeats)])


def beside_busy_process(bundle, method: Method, storyboard: Storyboard, config: SpeedConfig,
                        index=None, log=None) -> dict:
    """{"method", "quiet": _medians, "busy": _medians, "ratio", "target", "met"}: `method` in
    turns without and with CompetingLoad, busy_repeats times each."""
    quiet, busy = [], []
    for r in range(config.busy_repeats):
        quiet.append(_timed_run(bundle, method, storyboard, r, index))
        with CompetingLoad():
            busy.append(_timed_run(bundle, method, storyboard, r, index))
        if log:
            log(f"speed {method.label} quiet / beside a busy loop (round {r + 1}): "
                f"{quiet[-1]['wall_s']:.2f} / {busy[-1]['wall_s']:.2f} s")
    out = {"method": method.key, "quiet": _medians(quiet), "busy": _medians(busy), "target": config.busy_target}
    out["ratio"] = out["busy"]["wall_s"] / out["quiet"]["wall_s"]
    out["met"] = out["ratio"] <= config.busy_target
    return out


def without_object(sb: Storyboard) -> Storyboard:
    """The same storyboard with its objects and object contacts removed (2 people only)."""
    return replace(sb, objects=[], object_keys=[], object_paths=[],
                   contacts=[c for c in sb.contacts if c.object is None])


def speed_table(bundle, methods: tuple[Method, ...], scaling_methods: tuple[Method, ...],
                storyboards_by_length: dict[float, Storyboard], config: SpeedConfig = SpeedConfig(),
                index=None, log=None) -> dict:
    """{"per_method": {key: measure()}, "length": {key: {seconds: wall}}, "entities": {key: {...}}}.
    storyboards_by_length must hold 6.0 (the per-method scene) and every config.lengths_s;
    scaling_methods must be among methods (the entity comparison reuses their 6 s figure)."""
    base = storyboards_by_length[6.0]
    methods = tuple(m for m in methods if m.available(bundle))
    generate(bundle, methods[0], base, index=index)          # warm-up, untimed
    out: dict = {"per_method": {}, "length": {}, "entities": {}}
    repeats = {m.key: config.ddpm_repeats if m.sampler is not None and m.sampler.method == "teacher-ddpm"
               else config.repeats for m in methods}
    runs: dict[str, list] = {m.key: [] for m in methods}
    for r in range(max(repeats.values())):       # round r: every method once, in turn
        for m in methods:
            if r < repeats[m.key]:
                runs[m.key].append(_timed_run(bundle, m, base, r, index))
                if log:
                    log(f"speed {m.label} (round {r + 1}): {runs[m.key][-1]['wall_s']:.2f} s")
    out["per_method"] = {m.key: {**_medians(runs[m.key]), "peak_rss_mib": peak_memory_mib(bundle, m, base, index)}
                         for m in methods}
    if config.busy_repeats:
        out["busy"] = beside_busy_process(bundle, methods[0], base, config, index, log)
    for m in scaling_methods:
        out["length"][m.key] = {f"{s:g}": measure(bundle, m, storyboards_by_length[s], config.scaling_repeats,
                                                  index)["wall_s"] for s in config.lengths_s}
        out["entities"][m.key] = {
            "2 people": measure(bundle, m, without_object(base), config.scaling_repeats, index)["wall_s"],
            "2 people + 1 object": out["per_method"][m.key]["wall_s"]}
    return out
