"""Rotation representations: matrices, the continuous 6D form, quaternions, axis-angle.

All functions take numpy arrays with arbitrary leading batch dimensions.
6D convention (Zhou et al. 2019): the first two *columns* of the rotation matrix,
concatenated as [c0x, c0y, c0z, c1x, c1y, c1z]. Quaternions are (w, x, y, z).
"""
from __future__ import annotations

import numpy as np

EPS = 1e-9


def normalize(v: np.ndarray) -> np.ndarray:
    """(..., D) vectors scaled to unit length (zero ones stay zero)."""
    return v / np.maximum(norm(v, keepdims=True), EPS)


def norm(v: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Euclidean length of (..., D) vectors -> (...) (or (..., 1)), its squares summed written out:
    equal to np.linalg.norm(v, axis=-1) to the bit, several times faster on the finishing's
    batches (the norm reduces over a short last axis slowly)."""
    squares = v[..., 0] * v[..., 0]
    for i in range(1, v.shape[-1]):
        squares = squares + v[..., i] * v[..., i]
    out = np.sqrt(squares)
    return out[..., None] if keepdims else out


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross of (..., 3) vectors, written out: several times faster on the small batches of
    the finishing's kinematics (np.cross moves axes about for every call)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def matrix_to_6d(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 6)."""
    return np.concatenate([R[..., :, 0], R[..., :, 1]], axis=-1)


def sixd_to_matrix(d6: np.ndarray) -> np.ndarray:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt; any non-degenerate 6D vector maps to a rotation."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = normalize(a1)
    b2 = normalize(a2 - np.sum(b1 * a2, axis=-1, keepdims=True) * b1)
    b3 = cross(b1, b2)
    return np.stack([b1, b2, b3], axis=-1)


def axis_angle_to_matrix(aa: np.ndarray) -> np.ndarray:
    """Rodrigues: (..., 3) rotation vectors -> (..., 3, 3)."""
    angle = np.linalg.norm(aa, axis=-1, keepdims=True)
    axis = aa / np.maximum(angle, EPS)
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    zero = np.zeros_like(x)
    K = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=-1).reshape(aa.shape[:-1] + (3, 3))
    s, c = np.sin(angle)[..., None], np.cos(angle)[..., None]
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + s * K + (1 - c) * (K @ K)


def matrix_to_axis_angle(R: np.ndarray) -> np.ndarray:
    """Inverse of axis_angle_to_matrix, angles in [0, pi]: (..., 3, 3) -> (..., 3)."""
    q = matrix_to_quat(R)                                   # w >= 0, so the angle is <= pi
    s = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2 * np.arctan2(s, q[..., :1])
    return q[..., 1:] * angle / np.maximum(s, EPS)


def euler_to_matrix(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """Intrinsic rotations in the given axis order, e.g. 'ZXY' as BVH channels list them.

    angles_deg: (..., len(order)) in degrees -> (..., 3, 3) = R_order[0] @ R_order[1] @ ...
    """
    R = np.broadcast_to(np.eye(3), angles_deg.shape[:-1] + (3, 3)).copy()
    for i, ax in enumerate(order.upper()):
        aa = np.zeros(angles_deg.shape[:-1] + (3,))
        aa[..., "XYZ".index(ax)] = np.deg2rad(angles_deg[..., i])
        R = R @ axis_angle_to_matrix(aa)
    return R


def matrix_to_euler(R: np.ndarray, order: str) -> np.ndarray:
    """Inverse of euler_to_matrix for a proper 3-axis Tait-Bryan order. (..., 3, 3) -> (..., 3) degrees."""
    i, j, k = ("XYZ".index(a) for a in order.upper())
    # Sign of the permutation decides the signs in the closed form.
    sign = 1.0 if (j - i) % 3 == 1 else -1.0
    sb = np.clip(sign * R[..., i, k], -1.0, 1.0)
    b = np.arcsin(sb)
    a = np.arctan2(-sign * R[..., j, k], R[..., k, k])
    c = np.arctan2(-sign * R[..., i, j], R[..., i, i])
    return np.rad2deg(np.stack([a, b, c], axis=-1))


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) wxyz (normalised here) -> (..., 3, 3)."""
    w, x, y, z = np.moveaxis(normalize(q), -1, 0)
    return np.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], axis=-1).reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 4) wxyz with w >= 0 (numerically stable branch per element)."""
    m = R.reshape(-1, 3, 3)
    tr = np.trace(m, axis1=1, axis2=2)
    cands = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    best = np.argmax(cands, axis=1)
    q = np.empty((m.shape[0], 4))
    for b in range(4):
        sel = best == b
        if not np.any(sel):
            continue
        r = m[sel]
        if b == 0:
            s = np.sqrt(1.0 + tr[sel]) * 2
            q[sel] = np.stack([0.25 * s, (r[:, 2, 1] - r[:, 1, 2]) / s,
                               (r[:, 0, 2] - r[:, 2, 0]) / s, (r[:, 1, 0] - r[:, 0, 1]) / s], 1)
        else:
            i = b - 1
            j, k = (i + 1) % 3, (i + 2) % 3
            s = np.sqrt(np.maximum(1.0 + r[:, i, i] - r[:, j, j] - r[:, k, k], EPS)) * 2
            out = np.empty((r.shape[0], 4))
            out[:, 0] = (r[:, k, j] - r[:, j, k]) / s
            out[:, 1 + i] = 0.25 * s
            out[:, 1 + j] = (r[:, j, i] + r[:, i, j]) / s
            out[:, 1 + k] = (r[:, k, i] + r[:, i, k]) / s
            q[sel] = out
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return normalize(q).reshape(R.shape[:-2] + (4,))


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking direction a to direction b. (..., 3), (..., 3) -> (..., 3, 3)."""
    a, b = normalize(a), normalize(b)
    v = cross(a, b)
    c = np.sum(a * b, axis=-1)
    # Rodrigues without the angle, written out (the finishing's IK calls this most):
    # R = c I + [v]x + v v^T / (1 + c).
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    k = 1.0 / np.maximum(1.0 + c, 1e-12)
    kx, ky = k * x, k * y
    kxy, kxz, kyz = kx * y, kx * z, ky * z
    out = np.stack([c + kx * x, kxy - z, kxz + y,
                    kxy + z, c + ky * y, kyz - x,
                    kxz - y, kyz + x, c + k * z * z], axis=-1).reshape(v.shape[:-1] + (3, 3))
    anti = c < -1.0 + 1e-6   # near antiparallel: a half turn about an axis across a
    if np.any(anti):
        a = np.broadcast_to(a, v.shape)   # a may come unbroadcast (the IK's offsets)
        helper = np.where(np.abs(a[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
        out[anti] = axis_angle_to_matrix(np.pi * normalize(np.cross(a, helper)))[anti]
    return out


def _flat(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    return (3 * (i % 3) + j % 3).ravel()


# Entry (i, j) of a 3x3 matrix's cofactor matrix is m[i+1, j+1] m[i+2, j+2] - m[i+1, j+2] m[i+2, j+1]
# (indices mod 3): the flat indices of those four factors, the two products' first factors in one
# gather and their second in another.
_ROWS, _COLS = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
_COFACTOR_LEFT = np.concatenate([_flat(_ROWS + 1, _COLS + 1), _flat(_ROWS + 1, _COLS + 2)])
_COFACTOR_RIGHT = np.concatenate([_flat(_ROWS + 2, _COLS + 2), _flat(_ROWS + 2, _COLS + 1)])


def kabsch(src: np.ndarray, dst: np.ndarray, iterations: int = 8) -> np.ndarray:
    """Rotation R minimising sum |R src_i - dst_i|^2. src, dst: (..., P, 3) -> (..., 3, 3).

    R is the orthogonal polar factor of M = dst^T src, found by scaled Newton iterations
    M <- (g M + M^-T / g) / 2, g = |det M|^(-1/3) (Higham 1986), with 3x3 inverses from
    cofactors, on the nine entries flat: three times as fast as a batched SVD (the finishing's IK
    calls this twice per pose batch). Where that fails to converge to a rotation (a reflection,
    a degenerate M), the SVD answers."""
    lead = src.shape[:-2]
    # (9, batch): entry-major, so that the cofactors' gathers copy rows (a third faster)
    m = (np.swapaxes(dst, -1, -2) @ src).reshape(-1, 9).T.copy()
    with np.errstate(divide="ignore", invalid="ignore"):   # a singular M: failed below
        for _ in range(iterations):
            products = m[_COFACTOR_LEFT] * m[_COFACTOR_RIGHT]
            cofactors = products[:9] - products[9:]                               # det M * M^-T
            det = m[0] * cofactors[0] + m[1] * cofactors[1] + m[2] * cofactors[2]
            scale = np.abs(det) ** (-1 / 3)
            m = 0.5 * (scale * m + cofactors / (scale * det))
        m = m.T.reshape(lead + (3, 3))
        error = np.abs(np.swapaxes(m, -1, -2) @ m - np.eye(3)).max((-1, -2))
        det = np.sum(m[..., 0, :] * cross(m[..., 1, :], m[..., 2, :]), axis=-1)
        failed = ~((error < 1e-10) & (det > 0))
    if np.any(failed):
        m[failed] = _kabsch_svd(src[failed], dst[failed])
    return m


def _kabsch_svd(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(np.swapaxes(src, -1, -2) @ dst)
    V = np.swapaxes(Vt, -1, -2).copy()
    V[..., :, 2] *= np.sign(np.linalg.det(V) * np.linalg.det(U))[..., None]   # a rotation, never a reflection
    return V @ np.swapaxes(U, -1, -2)
