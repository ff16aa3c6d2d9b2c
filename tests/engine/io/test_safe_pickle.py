"""CORE4D's pickled pose dicts are read without running code: arrays and plain containers come
back, anything else in the stream (a crafted file calling os.system) is refused in one line."""
import os
import pickle
import zipfile

import numpy as np
import pytest

from engine.io.core4d import _person_joints
from engine.io.retarget import RetargetError
from engine.io.safe_pickle import load_pickled_entry


class Exploit:
    def __reduce__(self):
        return os.system, ("touch /tmp/sketch2colab_pwned",)


def test_a_pose_dict_comes_back(tmp_path):
    path = tmp_path / "person1_poses.npz"
    joints = np.random.default_rng(0).normal(size=(5, 127, 3))
    np.savez(path, {"joints": joints, "betas": np.zeros(10), "gender": "neutral"})
    params = load_pickled_entry(path)
    assert params["gender"] == "neutral" and np.array_equal(params["joints"], joints)
    assert _person_joints(path).shape == (5, 22, 3)


def test_a_crafted_file_runs_no_code(tmp_path):
    marker = "/tmp/sketch2colab_pwned"
    if os.path.exists(marker):
        os.remove(marker)
    path = tmp_path / "person1_poses.npz"
    array = np.empty((), dtype=object)
    array[()] = {"joints": Exploit()}
    with zipfile.ZipFile(path, "w") as archive, archive.open("arr_0.npy", "w") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "|O", "fortran_order": False, "shape": ()})
        pickle.dump(array, f, protocol=3)
    with pytest.raises(pickle.UnpicklingError, match="os|posix|system"):
        load_pickled_entry(path)
    with pytest.raises(RetargetError) as info:
        _person_joints(path)
    assert "\n" not in str(info.value) and not os.path.exists(marker)
