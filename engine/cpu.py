"""How many torch threads to use: the cores this process may use, less what other programs keep busy.

torch's OpenMP threads wait for each other at the end of every operation. With more threads than
free cores, every operation waits for a thread the kernel has descheduled: beside one busy loop on
2 cores, a generation that takes 0.75 s with 1 thread took 36.6 s with 2. So the sampler, the app's
worker, training and the benchmark all take their thread count from `choose_threads`, which
measures the other programs' load on our cores over a short window, and again as the run goes on
(`ThreadBudget`).

The override, in order: an explicit count (`--threads`, the app's preference), then the environment
variable SKETCH2COLAB_THREADS; a count is still capped at the cores this process may use.
"""
from __future__ import annotations

import math
import os
import threading
import time
from dataclasses import dataclass

ENV_VAR = "SKETCH2COLAB_THREADS"
MIN_WINDOW_S = 0.03     # shorter readings are too coarse (the kernel counts CPU time in 10 ms ticks)
STALE_S = 2.0           # a window longer than this averages away a load that just started
SPARE_CORE = 0.7        # a core counts as free when others leave at least this much of it idle


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity, capped by a cgroup CPU quota."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    try:
        quota, period = open("/sys/fs/cgroup/cpu.max").read().split()[:2]
        if quota != "max":
            cores = min(cores, max(1, math.ceil(int(quota) / int(period))))
    except (OSError, ValueError):
        pass
    return max(1, cores)


def threads_override(explicit: int | None = None) -> int | None:
    """The thread count the user asked for (an argument, else SKETCH2COLAB_THREADS), or None."""
    if explicit:
        return explicit
    value = os.environ.get(ENV_VAR, "").strip()
    if not value:
        return None
    try:
        count = int(value)
    except ValueError:
        raise ValueError(f"{ENV_VAR}={value!r}: expected a whole number of threads") from None
    if count < 1:
        raise ValueError(f"{ENV_VAR}={value!r}: expected at least 1 thread")
    return count


@dataclass
class _Reading:
    wall: float      # seconds, monotonic
    busy: float      # CPU seconds spent on our cores by everything, steal time included
    own: float       # CPU seconds spent by this process (all its threads)


def _read() -> _Reading:
    own = sum(os.times()[:2])
    busy = math.nan
    try:
        cpus = {f"cpu{i}" for i in os.sched_getaffinity(0)}
        tick = os.sysconf("SC_CLK_TCK")
        busy = 0.0
        with open("/proc/stat") as stat:
            for line in stat:
                if not line.startswith("cpu"):
                    break
                name, *fields = line.split()
                if name in cpus:  # user nice system idle iowait irq softirq steal ...
                    f = [int(x) for x in fields[:8]]
                    busy += (f[0] + f[1] + f[2] + f[5] + f[6] + f[7]) / tick
    except (OSError, AttributeError, ValueError):
        busy = math.nan  # no /proc: nothing is known of the others
    return _Reading(time.monotonic(), busy, own)


class CpuLoad:
    """Cores kept busy by other programs between two readings (their share of our cores)."""

    def __init__(self):
        self._last = _read()
        self._lock = threading.Lock()

    def others(self) -> float:
        """Cores' worth of CPU time others used since the last reading (0 when unknown). Waits
        for MIN_WINDOW_S when the last reading is too recent; a stale one starts a fresh window."""
        with self._lock:
            return self._others()

    def _others(self) -> float:
        now = _read()
        if now.wall - self._last.wall > STALE_S:
            self._last = now
            time.sleep(MIN_WINDOW_S)
            now = _read()
        elif now.wall - self._last.wall < MIN_WINDOW_S:
            time.sleep(MIN_WINDOW_S - (now.wall - self._last.wall))
            now = _read()
        window = now.wall - self._last.wall
        others = (now.busy - self._last.busy - (now.own - self._last.own)) / window
        self._last = now
        return 0.0 if math.isnan(others) else max(0.0, others)


# One reading for the process, started at import: the first choice measures over the start-up's
# window, and each later one over the time since the previous choice, without waiting.
_PROCESS_LOAD = CpuLoad()


def choose_threads(explicit: int | None = None, reserve: float = 0.0, load: CpuLoad | None = None) -> int:
    """Torch threads for the next piece of work: the override when one is set (capped at the
    usable cores), else the usable cores that others and `reserve` (cores kept for our own other
    work, e.g. software OpenGL drawing) leave free; at least 1."""
    cores = usable_cores()
    asked = threads_override(explicit)
    if asked is not None:
        return max(1, min(asked, cores))
    others = (load or _PROCESS_LOAD).others()
    return max(1, min(cores, math.floor(cores - others - reserve + (1 - SPARE_CORE))))


class ThreadBudget:
    """Keeps torch's thread count right during a long run: `adjust()` between steps re-measures
    every `every_s` seconds and changes the count only when the load has changed."""

    def __init__(self, explicit: int | None = None, reserve: float = 0.0, every_s: float = 0.25):
        self.explicit, self.reserve, self.every_s = explicit, reserve, every_s
        self._checked = -math.inf
        self.threads = 0

    def adjust(self) -> int:
        """Set torch's thread count for what follows; returns it. Cheap between re-measurements."""
        now = time.monotonic()
        if now - self._checked >= self.every_s:
            self._checked = now
            threads = choose_threads(self.explicit, self.reserve)
            if threads != self.threads:
                import torch
                torch.set_num_threads(threads)
                self.threads = threads
        return self.threads
