"""Reading a pickled entry of an .npz (CORE4D keeps its pose dicts so) without running code.

`np.load(..., allow_pickle=True)` would run whatever a crafted file asks for. Here the pickle is
read with an unpickler that rebuilds arrays, numbers, strings and plain containers only; any
other reference in the stream is refused with an UnpicklingError.
"""
from __future__ import annotations

import pickle
import zipfile
from pathlib import Path

import numpy as np

_ALLOWED = {
    ("numpy", "ndarray"), ("numpy", "dtype"),
    ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
    ("collections", "OrderedDict"),
}


class _ArraysOnly(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if (module, name) in _ALLOWED or (module.startswith("numpy") and name.endswith("DType")):
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"{module}.{name} is not allowed in a data file")


def load_pickled_entry(path: str | Path, key: str = "arr_0"):
    """The object stored under `key` in the .npz at `path` (np.savez of a dict: a 0-d object
    array, returned as its item). Raises pickle.UnpicklingError, zipfile.BadZipFile, KeyError
    or ValueError on a file that is not such an entry."""
    with zipfile.ZipFile(path) as archive, archive.open(f"{key}.npy") as f:
        version = np.lib.format.read_magic(f)
        read_header = {(1, 0): np.lib.format.read_array_header_1_0,
                       (2, 0): np.lib.format.read_array_header_2_0}.get(version)
        if read_header is None:
            raise ValueError(f"unsupported .npy version {version}")
        shape, _, dtype = read_header(f)
        if dtype != np.dtype(object):
            raise ValueError(f"{key} holds {dtype} data, not a pickled object")
        array = _ArraysOnly(f).load()
    if not isinstance(array, np.ndarray) or array.shape != tuple(shape):
        raise ValueError(f"{key} does not hold the array its header describes")
    return array.item() if array.shape == () else array
