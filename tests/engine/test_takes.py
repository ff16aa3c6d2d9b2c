"""Takes kept beside their storyboard (engine/takes.py): every variation, seed and setting back
exactly, the newest MAX_TAKES kept, a damaged file refused in one line."""
import numpy as np
import pytest

from engine.synth import synthesize
from engine.takes import MAX_TAKES, Take, TakesError, load_takes, save_takes, takes_path


def take(seed: int, variations: int = 2) -> Take:
    clips = [synthesize("handoff", seed + k, fps=20) for k in range(variations)]
    return Take(clips, seed, {"steps": 30, "cfg": 1.6}, '{"storyboard": %d}' % seed, chosen=variations - 1)


def test_takes_come_back_exactly(tmp_path):
    takes = [take(1), take(2, variations=1)]
    path = takes_path(tmp_path / "handoff.json")
    assert path.name == "handoff.takes.npz"
    save_takes(takes, path)
    again = load_takes(path)
    assert [(t.seed, t.settings, t.source, t.chosen, t.created) for t in again] == \
        [(t.seed, t.settings, t.source, t.chosen, t.created) for t in takes]
    for a, b in zip(again, takes):
        assert len(a.clips) == len(b.clips)
        for x, y in zip(a.clips, b.clips):
            assert np.array_equal(x.joints, y.joints) and np.array_equal(x.obj_pose, y.obj_pose) and x.fps == y.fps


def test_only_the_newest_takes_are_kept(tmp_path):
    path = tmp_path / "many.takes.npz"
    save_takes([take(i, variations=1) for i in range(MAX_TAKES + 2)], path)
    assert [t.seed for t in load_takes(path)] == list(range(2, MAX_TAKES + 2))


@pytest.mark.parametrize("damage", [b"", b"not a zip at all", None])
def test_a_damaged_takes_file_is_refused_in_one_line(tmp_path, damage):
    path = tmp_path / "bad.takes.npz"
    if damage is None:                       # a readable NPZ without an index
        np.savez(path, joints=np.zeros(3))
    else:
        path.write_bytes(damage)
    with pytest.raises(TakesError) as info:
        load_takes(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)
