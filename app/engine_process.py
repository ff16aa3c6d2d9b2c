"""Generation in a process of its own: the window's process never loads the model.

On the generation thread a run shares the interpreter lock with the GUI thread, which draws while
it runs: on 2 cores under Xvfb the live preview of the resting pointer ran 86-130 ms in the app
against 52-75 ms alone, and a full generation after a drag's release 468-543 ms against 260-410.
In a child process the two run side by side (scripts/preview_latency.py, alternated with previews
on the thread: pointer stop to picture, median 221 / 268 ms -> 152 / 126 ms, worst 254 / 319 ->
223 / 229 ms).

The child (`python -m app.engine_process FD [WARM_UP_STORYBOARD]`; a multiprocessing spawn would
re-run the parent's main script, which a program started from a pipe or `-c` lacks) loads the
model, warms the full and the preview path up and says it is ready; a run asked for before waits
for it. It serves one run at a time:

    parent -> child   ("run", run, storyboard, settings) | ("cancel", run) | ("quit",)
    child -> parent   ("ready",) | ("step", run, step, num_steps, t, phase, energies, motion)
                      | ("done", run, result) | ("failed", run, exception) | ("cancelled", run)

A step's `motion` is decoded in the child for the steps the views are to show (at most one per
STEP_INTERVAL_S, and the last; none of a live preview's: GenerationSettings.streams_steps), None
for the rest, which come so that a cancel is seen between any two steps. A new run or a cancel
reaching the child mid-run stops it between steps, or between the stages of its finishing (half a
full generation's time: a drag begun just after a release waited for it). The child exits when the
parent's end of the socket closes, so a killed app leaves no process behind; a child that stopped
is started again by the next run.
"""
from __future__ import annotations

import os
import pickle
import socket
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable, Generator
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np

from engine.sampling.events import StepEvent
from engine.storyboard import Storyboard

from .generation import STEP_INTERVAL_S, GenerationSettings, StepStream, start_generation, warm_up


class EngineProcess:
    def __init__(self, warm_up_storyboard: Path | None = None):
        """Starts the child now: it loads the model (and warms up on `warm_up_storyboard`) while
        the window opens."""
        self._warm_up = warm_up_storyboard
        self._sending = threading.Lock()    # the GUI thread (close) and the generation thread send
        self._run = 0
        self._process: subprocess.Popen | None = None
        self._start()

    def _start(self) -> None:
        self._ready = False
        ours, theirs = socket.socketpair()
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(__file__).parents[1]),
                                                                         os.environ.get("PYTHONPATH")]))}
        try:
            self._process = subprocess.Popen(
                [sys.executable, "-m", "app.engine_process", str(theirs.fileno()), str(self._warm_up or "")],
                pass_fds=[theirs.fileno()], env=env, stdin=subprocess.DEVNULL)
        except OSError as e:   # the run that needs it says so
            print(f"the generation process did not start: {e}", file=sys.stderr)
            self._process = None
        theirs.close()
        self._conn = Connection(ours.detach())

    @property
    def alive(self) -> bool:
        return self._process is not None and self._process.poll() is None

    @property
    def ready(self) -> bool:
        """The child is up and warmed up (read where runs start: until it is, no run uses the socket)."""
        if not self._ready and self.alive:
            try:
                self._ready = self._conn.poll() and self._conn.recv() == ("ready",)
            except (EOFError, OSError):
                pass
        return self._ready and self.alive

    def generate(self, storyboard: Storyboard, settings: GenerationSettings) -> "RemoteStream":
        """The child's run of the request (what the session runs): its steps, the motion of those
        to show decoded, ending with its result; closing the stream early, or its cancel(), cancels
        the run."""
        self._run += 1
        run = self._run

        def cancel() -> None:
            self._send(("cancel", run))

        return RemoteStream(self._answers(run, storyboard, settings, cancel), cancel)

    def _answers(self, run: int, storyboard: Storyboard, settings: GenerationSettings,
                 cancel: Callable[[], None]) -> StepStream:
        if not self.alive:            # it stopped (or never started): another, its model loaded anew
            self._conn.close()
            self._start()
        while not self.ready:         # on the generation thread: the window goes on meanwhile
            if not self.alive:
                raise RuntimeError("the generation process stopped while it started (see the terminal)")
            self._conn.poll(0.05)
        ended = False
        self._send(("run", run, storyboard, settings))
        try:
            while True:
                try:
                    message = self._conn.recv()      # waits without the interpreter lock
                except (EOFError, OSError):
                    ended = True
                    raise RuntimeError("the generation process stopped") from None
                if message[1] != run:                # the last words of a run cancelled before
                    continue
                kind = message[0]
                if kind == "step":
                    yield _step_event(*message[2:])
                    continue
                ended = True
                if kind == "done":
                    return message[2]
                if kind == "failed":
                    raise message[2]
                raise RuntimeError("the run was cancelled in the generation process")
        finally:
            if not ended:
                cancel()

    def _send(self, message: tuple) -> None:
        with self._sending:
            try:
                self._conn.send(message)
            except (BrokenPipeError, OSError):
                pass                                 # the child is gone: the next recv says so

    def close(self, timeout_s: float = 2.0) -> None:
        """Ask the child to quit and wait for it (then end it)."""
        self._send(("quit",))
        if self._process is not None:
            try:
                self._process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait(timeout_s)
        self._conn.close()


class RemoteStream(Generator):
    """A run in the child as a StepStream that can also be cancelled from another thread while
    its own waits for the child (cancel(), thread-safe): the child stops at its next step or
    finishing stage and the stream ends in a RuntimeError. Closing it cancels as well."""

    def __init__(self, answers: StepStream, cancel: Callable[[], None]):
        self._answers, self.cancel = answers, cancel

    def send(self, value):
        return self._answers.send(value)

    def throw(self, *error):
        return self._answers.throw(*error)


def _step_event(step: int, num_steps: int, t: float, phase: np.ndarray, energies: dict, motion) -> StepEvent:
    """A step from the child: its motion decoded there (and so handed to the views at once,
    app.worker), or None (not to be shown)."""
    event = StepEvent(step, num_steps, t, np.zeros(0), None if motion is None else (lambda: motion), phase, energies)
    if motion is not None:
        event.preview   # cached: the worker sees it decoded
    return event


def serve(conn, warm_up_storyboard: Path | None) -> None:
    """The child's loop (conn: its end of the socket). Returns on quit or when the app is gone."""
    if warm_up_storyboard is not None:
        for settings in (GenerationSettings(steps=2), GenerationSettings(preview=True)):
            warm_up(warm_up_storyboard, settings)
    try:
        conn.send(("ready",))
        waiting = None
        while True:
            message = waiting or conn.recv()
            waiting = None
            if message[0] == "quit":
                return
            if message[0] == "run":
                waiting = _run(conn, *message[1:])
    except (EOFError, OSError):
        return   # the app closed its end: it has quit or was killed


class _Stopped(Exception):
    """A message that ends the run came: `message`, handled once the run is wound up."""

    def __init__(self, message: tuple):
        super().__init__(message[0])
        self.message = message


def _run(conn, run: int, storyboard: Storyboard, settings: GenerationSettings) -> tuple | None:
    """One run to its end, answered on conn; returns the message that stopped it, if one did (a
    newer run, or quit: handled next)."""
    def checkpoint() -> None:   # between steps, and between the finishing's stages
        while conn.poll():
            message = conn.recv()
            if message[0] != "cancel" or message[1] == run:   # else a cancel of a run already answered
                raise _Stopped(message)

    stream, shown = start_generation(storyboard, settings, checkpoint), -float("inf")
    try:
        while True:
            checkpoint()
            try:
                event = next(stream)
            except StopIteration as stop:
                conn.send(("done", run, stop.value))
                return None
            motion, now = None, time.monotonic()
            if settings.streams_steps and (now - shown >= STEP_INTERVAL_S or event.step == event.num_steps - 1):
                motion, shown = event.preview, now
            conn.send(("step", run, event.step, event.num_steps, event.t, event.phase, event.energies, motion))
    except _Stopped as stopped:
        stream.close()
        conn.send(("cancelled", run))
        return None if stopped.message[0] == "cancel" else stopped.message
    except (EOFError, OSError):
        raise                                        # the app is gone: serve returns
    except Exception as e:   # noqa: BLE001  the app reports it as its own run's failure, in one line
        traceback.print_exc()
        stream.close()
        conn.send(("failed", run, _sendable(e)))
        return None


def _sendable(error: Exception) -> Exception:
    """The error itself when it pickles (the app shows its type and first line), else its line."""
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:  # noqa: BLE001
        return RuntimeError(f"{type(error).__name__}: {error}".splitlines()[0])


if __name__ == "__main__":   # the child: python -m app.engine_process FD [WARM_UP_STORYBOARD]
    serve(Connection(int(sys.argv[1])), Path(sys.argv[2]) if len(sys.argv) > 2 and sys.argv[2] else None)
