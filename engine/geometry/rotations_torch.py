"""Rotations in torch, differentiable and cheap in ops (the guidance energies call them ~26 times a
generation on small tensors, where the number of ops, not flops, is the cost)."""
from __future__ import annotations

import functools

import numpy as np
import torch
from torch import Tensor

EPS = 1e-12


def safe_norm(v: Tensor) -> Tensor:
    """Euclidean norm over the last axis with a finite gradient at 0. (..., D) -> (...)."""
    return torch.sqrt(torch.linalg.vecdot(v, v) + EPS)


def _quat_product_table() -> np.ndarray:
    """(16, 9): R - I = 2 * (q q^T).flatten() @ table for a unit quaternion q = (w, x, y, z);
    row 4a + b holds the sign of the product q_a q_b in each entry of the textbook formula."""
    entries = {(0, 0): "-yy -zz", (0, 1): "+xy -wz", (0, 2): "+xz +wy",
               (1, 0): "+xy +wz", (1, 1): "-xx -zz", (1, 2): "+yz -wx",
               (2, 0): "+xz -wy", (2, 1): "+yz +wx", (2, 2): "-xx -yy"}
    table = np.zeros((16, 9))
    for (row, col), terms in entries.items():
        for sign, a, b in terms.split():
            table[4 * "wxyz".index(a) + "wxyz".index(b), 3 * row + col] = 1.0 if sign == "+" else -1.0
    return table


_TABLES = {"quat": _quat_product_table(), "eye3": np.eye(3).ravel()}


@functools.lru_cache(maxsize=32)
def _table(name: str, dtype: torch.dtype, device: torch.device) -> Tensor:
    """A table as a tensor, made once per dtype and device (shared: never modify it in place)."""
    return torch.as_tensor(_TABLES[name], dtype=dtype, device=device)


def quat_to_matrix(q: Tensor) -> Tensor:
    """(..., 4) wxyz, normalised here -> (..., 3, 3); an all-zero quaternion (the padded pose of
    an absent object) gives the identity. One matmul over the outer product instead of nine
    expressions (a few ops instead of ~40); each entry is the same two-product sum, so the
    values are the formula's."""
    q = q / safe_norm(q)[..., None]
    products = (q[..., :, None] * q[..., None, :]).flatten(-2)               # (..., 16)
    r = 2 * (products @ _table("quat", q.dtype, q.device)) + _table("eye3", q.dtype, q.device)
    return r.reshape(*q.shape[:-1], 3, 3)


def world_to_local(points: Tensor, pose: Tensor) -> Tensor:
    """World points (..., P, 3) into the frame of pose (..., 7: xyz + wxyz) -> (..., P, 3)."""
    R = quat_to_matrix(pose[..., 3:])
    return (points - pose[..., None, :3]) @ R
