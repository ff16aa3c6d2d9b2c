"""Live previews in a process of their own.

On the generation thread a preview shares the interpreter lock with the GUI thread, which draws
the last preview while the next one runs: on 2 cores under Xvfb the preview of the resting pointer
ran 86-130 ms in the app against 52-75 ms alone. In a child process the two run side by side
(scripts/preview_latency.py, alternated with previews on the thread: pointer stop to picture,
median 221 / 268 ms -> 152 / 126 ms, worst 254 / 319 -> 223 / 229 ms). The price is a second copy
of the model in memory (the child: 340 MB resident). Full generations stay on the generation
thread: the steps they stream are decoded for the views where the model is, and a child's steps
would need decoding there and sending across.

The child loads the model, warms the preview path up and says it is ready; until then (and if it
ever stops) previews run on the generation thread as before. It serves one request at a time:

    parent -> child   ("preview", run, storyboard, settings) | ("cancel", run) | ("quit",)
    child -> parent   ("ready",) | ("step", run, step, num_steps, t, phase) | ("done", run, result)
                      | ("failed", run, exception) | ("cancelled", run)

A request or a cancel reaching the child mid-run stops it between steps. The child exits when the
parent's end of the pipe closes, so a killed app leaves no process behind.
"""
from __future__ import annotations

import os
import pickle
import socket
import subprocess
import sys
import threading
import traceback
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np

from engine.sampling.events import StepEvent
from engine.storyboard import Storyboard

from .generation import GenerationSettings, StepStream, start_generation, warm_up


class PreviewProcess:
    def __init__(self, warm_up_storyboard: Path | None = None):
        """Starts the child now; it loads the model (and warms up on `warm_up_storyboard`) in the
        background. The app's first previews run on the generation thread meanwhile. The child is
        `python -m app.preview_process`, not a multiprocessing spawn: that re-runs the parent's
        main script, which a program started from a pipe or `-c` does not have."""
        self._sending = threading.Lock()    # the GUI thread (close) and the generation thread send
        self._ready = False
        self._run = 0
        ours, theirs = socket.socketpair()
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(__file__).parents[1]),
                                                                         os.environ.get("PYTHONPATH")]))}
        try:
            self._process = subprocess.Popen(
                [sys.executable, "-m", "app.preview_process", str(theirs.fileno()), str(warm_up_storyboard or "")],
                pass_fds=[theirs.fileno()], env=env, stdin=subprocess.DEVNULL)
        except OSError as e:   # no child: every preview runs here
            print(f"the preview process did not start: {e}", file=sys.stderr)
            self._process = None
        theirs.close()
        self._conn = Connection(ours.detach())

    @property
    def alive(self) -> bool:
        return self._process is not None and self._process.poll() is None

    @property
    def ready(self) -> bool:
        """The child is up and warmed up (read where runs start: until true no run uses the pipe)."""
        if not self._ready and self.alive:
            try:
                self._ready = self._conn.poll() and self._conn.recv() == ("ready",)
            except (EOFError, OSError):
                pass
        return self._ready and self.alive

    def generate(self, storyboard: Storyboard, settings: GenerationSettings) -> StepStream:
        """What the session runs: previews in the child once it is ready, the rest here."""
        if settings.preview and self.ready:
            return self._stream(storyboard, settings)
        return start_generation(storyboard, settings)

    def _stream(self, storyboard: Storyboard, settings: GenerationSettings) -> StepStream:
        """The child's run of the request as a stream of steps (not decoded: a preview hands none
        to the GUI) ending with its result; closing it early cancels the run."""
        self._run += 1
        run, ended = self._run, False
        self._send(("preview", run, storyboard, settings))
        try:
            while True:
                try:
                    message = self._conn.recv()      # waits without the interpreter lock
                except (EOFError, OSError):
                    ended = True
                    raise RuntimeError("the preview process stopped") from None
                if message[1] != run:                # the last words of a run cancelled before
                    continue
                kind = message[0]
                if kind == "step":
                    step, num_steps, t, phase = message[2:]
                    yield StepEvent(step, num_steps, t, np.zeros(0), _not_decoded, phase)
                    continue
                ended = True
                if kind == "done":
                    return message[2]
                if kind == "failed":
                    raise message[2]
                raise RuntimeError("the preview was cancelled in the preview process")
        finally:
            if not ended:
                self._send(("cancel", run))

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


def _not_decoded():
    raise RuntimeError("a preview's steps are not decoded in the app: only its result comes back")


def serve(conn, warm_up_storyboard: Path | None) -> None:
    """The child's loop (conn: its end of the pipe). Returns on quit or when the app is gone."""
    if warm_up_storyboard is not None:
        # on one thread: the app warms its own model up at the same moment, on the other core
        warm_up(warm_up_storyboard, GenerationSettings(preview=True, threads=1))
    try:
        conn.send(("ready",))
        waiting = None
        while True:
            message = waiting or conn.recv()
            waiting = None
            if message[0] == "quit":
                return
            if message[0] == "preview":
                waiting = _run(conn, *message[1:])
    except (EOFError, OSError):
        return   # the app closed its end: it has quit or was killed


def _run(conn, run: int, storyboard: Storyboard, settings: GenerationSettings) -> tuple | None:
    """One request to its end, answered on conn; returns the message that stopped it, if one did
    (a newer request, or quit: handled next)."""
    stream = start_generation(storyboard, settings)
    try:
        while True:
            if conn.poll():
                message = conn.recv()
                if message[0] != "cancel" or message[1] == run:
                    stream.close()
                    conn.send(("cancelled", run))
                    return None if message[0] == "cancel" else message
                continue                             # a cancel of a run already answered
            try:
                event = next(stream)
            except StopIteration as stop:
                conn.send(("done", run, stop.value))
                return None
            conn.send(("step", run, event.step, event.num_steps, event.t, event.phase))
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
        print(f"preview failed: {type(error).__name__}: {error}", file=sys.stderr)
        return RuntimeError(f"{type(error).__name__}: {error}".splitlines()[0])


if __name__ == "__main__":   # the child: python -m app.preview_process FD [WARM_UP_STORYBOARD]
    serve(Connection(int(sys.argv[1])), Path(sys.argv[2]) if len(sys.argv) > 2 and sys.argv[2] else None)
