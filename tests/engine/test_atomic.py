"""Files are written whole or not at all: concurrent writers, a writer killed mid-write and a
failing write never leave a half file or lose the previous one; bad output paths are refused
before any work, in one line."""
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from engine.atomic import OutputPathError, atomic_write, check_output_path, write_text
from engine.cli import main
from engine.storyboard import Agent, Storyboard


def test_concurrent_writers_never_leave_a_partial_file(tmp_path):
    path = tmp_path / "story.json"
    boards = [Storyboard(length=20 + 10 * i, agents=[Agent("A")]) for i in range(4)]
    errors = []

    def writer(board):
        for _ in range(25):
            board.save(path)

    def reader():
        for _ in range(200):
            if path.exists():
                try:
                    Storyboard.load(path)
                except Exception as e:  # noqa: BLE001  any failure to read is the bug
                    errors.append(e)

    threads = [threading.Thread(target=writer, args=(b,)) for b in boards] + [threading.Thread(target=reader)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == [] and Storyboard.load(path).length in {b.length for b in boards}
    assert [p.name for p in tmp_path.iterdir()] == ["story.json"]          # no temporary file left


def test_a_writer_killed_mid_write_leaves_the_previous_file(tmp_path):
    path = tmp_path / "motion.bin"
    path.write_bytes(b"previous")
    code = (f"import time\nfrom engine.atomic import atomic_write\n"
            f"with atomic_write({str(path)!r}) as f:\n"
            f"    f.write(b'x' * 1000)\n    f.flush()\n    print('writing', flush=True)\n    time.sleep(30)\n")
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "writing"
    os.kill(child.pid, signal.SIGKILL)
    child.wait()
    assert path.read_bytes() == b"previous"
    assert all(p.name.startswith(".") for p in tmp_path.iterdir() if p != path)   # only a hidden leftover


def test_a_failing_write_keeps_the_previous_file_and_cleans_up(tmp_path):
    path = tmp_path / "notes.txt"
    write_text(path, "kept")
    with pytest.raises(RuntimeError):
        with atomic_write(path) as f:
            f.write(b"half")
            raise RuntimeError("the disk filled up")
    assert path.read_text() == "kept" and [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


@pytest.mark.parametrize("bad, why", [("folder", "is a folder"), ("/dev/full", "not a regular file"),
                                      ("missing/x.npz", "does not exist")])
def test_bad_output_paths_are_refused(tmp_path, bad, why):
    (tmp_path / "folder").mkdir()
    target = bad if bad.startswith("/") else tmp_path / bad
    with pytest.raises(OutputPathError, match=why):
        check_output_path(target)


def test_generate_refuses_a_bad_output_before_generating(tmp_path, capsys):
    started = time.perf_counter()
    for bad in (tmp_path, "/dev/full"):
        code = main(["generate", "resources/examples/handshake.json", "-o", str(bad), "--steps", "30"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith("error:")
    assert time.perf_counter() - started < 5                 # refused, not generated then failed
    assert list(tmp_path.iterdir()) == []
