"""Thread counts follow the free cores (engine.cpu): overrides are capped, bad ones refused, and a
busy program beside us takes a thread away, in choose_threads and in a running generation."""
import subprocess
import sys
import time

import pytest
import torch

from engine.cpu import ENV_VAR, CpuLoad, ThreadBudget, choose_threads, threads_override, usable_cores
from engine.models.bundle import untrained_bundle
from engine.request import Request
from engine.sampling.config import SamplerConfig
from engine.sampling.sampler import sample
from engine.storyboard import Agent, Storyboard


@pytest.fixture
def busy_loop():
    process = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    time.sleep(0.3)
    yield process
    process.kill()
    process.wait()


@pytest.fixture(autouse=True)
def keep_torch_threads(monkeypatch):
    monkeypatch.delenv(ENV_VAR, raising=False)
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)


def test_overrides_are_capped_at_the_usable_cores(monkeypatch):
    cores = usable_cores()
    assert choose_threads(1) == 1
    assert choose_threads(cores + 7) == cores
    monkeypatch.setenv(ENV_VAR, "1")
    assert threads_override() == 1 and choose_threads() == 1
    assert choose_threads(cores) == cores            # an explicit count wins over the variable


@pytest.mark.parametrize("value", ["two", "0", "-3", "1.5"])
def test_a_bad_environment_variable_is_refused_in_one_line(monkeypatch, value):
    monkeypatch.setenv(ENV_VAR, value)
    with pytest.raises(ValueError, match=ENV_VAR):
        choose_threads()


def test_reserved_cores_are_left_free():
    assert choose_threads(reserve=usable_cores()) == 1        # never fewer than one
    assert choose_threads(reserve=1.0) <= max(1, usable_cores() - 1)


@pytest.mark.skipif(usable_cores() < 2, reason="needs at least 2 usable cores")
def test_a_busy_program_beside_takes_a_thread(busy_loop):
    load = CpuLoad()
    time.sleep(0.1)
    assert load.others() > 0.7
    assert choose_threads() <= usable_cores() - 1


@pytest.mark.skipif(usable_cores() < 2, reason="needs at least 2 usable cores")
def test_a_generation_drops_a_thread_when_a_busy_program_starts():
    """The sampler re-measures between steps: a load that starts mid-run is seen within it."""
    cores = usable_cores()
    steps = sample(untrained_bundle(), Request.build(Storyboard(length=40, agents=[Agent("A")]), SamplerConfig(steps=200, finish=False)))

    def step_until(done, seconds: float = 20.0) -> int:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            next(steps)
            if done(torch.get_num_threads()):
                break
        return torch.get_num_threads()

    try:
        quiet = step_until(lambda n: n == cores)   # a load that just ended (an earlier test's) fades
        with subprocess.Popen([sys.executable, "-c", "while True: pass"]) as process:
            try:
                busy = step_until(lambda n: n < cores)
            finally:
                process.kill()
    finally:
        steps.close()
    assert quiet == cores and busy < cores


def test_thread_budget_sets_torch_and_keeps_it_between_measurements(monkeypatch):
    budget = ThreadBudget(explicit=1, every_s=60.0)
    assert budget.adjust() == 1 and torch.get_num_threads() == 1
    torch.set_num_threads(2)
    assert budget.adjust() == 1                      # not re-measured within every_s
