"""Motion clip NPZ format and object geometry."""
import numpy as np
import pytest

from engine.clip import ClipError, MotionClip
from engine.geometry.rotations import axis_angle_to_matrix, matrix_to_quat, sixd_to_matrix
from engine.objects import ObjectSpec, local_to_world, world_to_local
from engine.skeleton import forward_kinematics


def two_people(n=10):
    rng = np.random.default_rng(0)
    aa = rng.normal(scale=0.3, size=(n, 2, 22, 3))
    root = np.stack([np.full((n, 3), [-0.6, 0.95, 0]), np.full((n, 3), [0.6, 0.95, 0])], 1)
    return forward_kinematics(root, axis_angle_to_matrix(aa))


def test_from_joints_save_load_round_trip(tmp_path):
    joints = two_people()
    pose = np.tile([0, 0, 0, 1, 0, 0, 0], (10, 1, 1)).astype(float)
    spec = ObjectSpec("box")
    anchors = local_to_world(np.broadcast_to(spec.anchors, (10, 1, 4, 3)), pose)
    clip = MotionClip.from_joints(joints, 20, obj_pose=pose, obj_anchors=anchors,
                                  obj_type=np.array(["box"]), obj_size=np.array([spec.size]),
                                  phase=np.tile([1, 0, 0], (10, 1)), contact=np.zeros((10, 2, 2)),
                                  scenario="test")
    fk = forward_kinematics(clip.joints[:, :, 0], sixd_to_matrix(clip.rot6d), clip.offsets()[None])
    assert np.abs(fk - joints).max() < 1e-5
    clip.save(tmp_path / "c.npz")
    back = MotionClip.load(tmp_path / "c.npz")
    assert back.scenario == "test" and back.fps == 20 and back.obj_type[0] == "box"
    assert np.array_equal(back.joints, clip.joints) and np.array_equal(back.obj_anchors, clip.obj_anchors)
    assert back.slice(2, 5).num_frames == 3 and back.slice(2, 5).phase.shape == (3, 3)


def test_bad_clips_are_rejected(tmp_path):
    with pytest.raises(ClipError, match="joints must be"):
        MotionClip(20, np.zeros((5, 2, 21, 3)), np.zeros((5, 2, 22, 6)))
    j = two_people(3)
    j[1, 0, 3, 1] = np.nan
    with pytest.raises(ClipError, match="NaN"):
        MotionClip(20, j, np.zeros((3, 2, 22, 6)))
    (tmp_path / "x.npz").write_bytes(b"not a zip")
    with pytest.raises(ClipError, match="not a readable"):
        MotionClip.load(tmp_path / "x.npz")
    np.savez(tmp_path / "y.npz", fps=20)
    with pytest.raises(ClipError, match="missing required array 'joints'"):
        MotionClip.load(tmp_path / "y.npz")


def inside_convex_parts(mesh, pts):
    """Inside test without spatial indices: a point is inside a convex part when it is behind
    every face plane; the mesh is the union of its connected (convex) parts."""
    inside = np.zeros(len(pts), bool)
    for part in mesh.split(only_watertight=False):
        d = np.einsum("fk,pfk->pf", part.face_normals, pts[:, None] - part.triangles[None, :, 0])
        inside |= np.all(d <= 0, axis=1)
    return inside


@pytest.mark.parametrize("kind", ["box", "table", "canister"])
def test_sdf_matches_mesh(kind):
    """Analytic SDF: negative exactly where the mesh says the point is inside."""
    spec = ObjectSpec(kind)
    mesh = spec.mesh()
    lo, hi = mesh.bounds
    pts = np.random.default_rng(1).uniform(lo - 0.1, hi + 0.1, size=(2000, 3))
    sdf = spec.sdf_local(pts)
    clear = np.abs(sdf) > 3e-3  # the canister mesh is a 24-gon: its faces sag ~1.3 mm from the circle
    assert np.array_equal((sdf < 0)[clear], inside_convex_parts(mesh, pts)[clear])
    assert (sdf < 0).sum() > 20
    if kind != "canister":
        assert np.all(np.abs(spec.sdf_local(np.asarray(mesh.vertices))) < 1e-6)  # vertices on the surface


@pytest.mark.parametrize("kind", ["box", "table", "canister"])
def test_penetration_is_the_sdf_depth_of_every_sphere(kind):
    """The bounding-sphere shortcut changes nothing: max(radius - sdf, 0) for near and far spheres."""
    spec = ObjectSpec(kind)
    lo, hi = spec.mesh().bounds
    rng = np.random.default_rng(3)
    pts = rng.uniform(lo - 0.6, hi + 0.6, size=(50, 40, 3))
    radii = rng.uniform(0.0, 0.3, size=40)
    depth = spec.penetration_local(pts, radii)
    assert np.array_equal(depth, np.maximum(radii - spec.sdf_local(pts), 0.0))
    assert 0 < np.mean(depth > 0) < 1


def test_object_pose_transforms_invert():
    pose = np.concatenate([[0.5, 0.2, -1.0], matrix_to_quat(axis_angle_to_matrix(np.array([0.1, 1.2, -0.3])))])
    p = np.random.default_rng(2).normal(size=(7, 3))
    assert np.allclose(world_to_local(local_to_world(p, pose), pose), p)
    assert ObjectSpec("box").anchors.shape == (4, 3)
