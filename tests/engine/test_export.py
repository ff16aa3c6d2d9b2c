"""Exports: NPZ round trip, one BVH per person read back, the object path CSV, and the animated
glb (container layout, node hierarchy, animation accessors, forward kinematics of the animation
reproducing the clip, trimesh reading the static scene)."""
import argparse
import csv
import json
import struct

import numpy as np
import pytest

from engine.clip import MotionClip
from engine.export import (add_export_arguments, export_bvh_dir, export_gltf, export_npz, export_object_path,
                           export_requested)
from engine.geometry.rotations import axis_angle_to_matrix, matrix_to_6d, quat_to_matrix
from engine.io.bvh import read_bvh
from engine.objects import ObjectSpec, local_to_world
from engine.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS, REST_PELVIS_HEIGHT, forward_kinematics

FRAMES = 30


def person(n, rng, x, yaw):
    """FK of smooth random joint rotations, walking along +Z. -> joints (N,22,3), rot6d (N,22,6)."""
    t = np.linspace(0.0, 1.0, n)[:, None, None]
    local = axis_angle_to_matrix(0.3 * np.sin(2 * np.pi * rng.uniform(0.5, 2, (1, 22, 3)) * t
                                              + rng.uniform(0, 6.3, (1, 22, 3))))
    local[:, 0] = axis_angle_to_matrix(np.array([0.0, yaw, 0.0])) @ local[:, 0]
    root = np.stack([np.full(n, x), np.full(n, REST_PELVIS_HEIGHT), np.linspace(0, 1.5, n)], -1)
    return forward_kinematics(root, local), matrix_to_6d(local)


@pytest.fixture(scope="module")
def clip():
    rng = np.random.default_rng(0)
    (ja, ra), (jb, rb) = person(FRAMES, rng, -0.6, np.pi / 2), person(FRAMES, rng, 0.6, -np.pi / 2)
    yaw = np.linspace(0, np.pi, FRAMES)  # the box turns half a turn: tests quaternion continuity
    pose = np.zeros((FRAMES, 1, 7))
    pose[:, 0, 1], pose[:, 0, 2] = 0.4, np.linspace(0, 1.5, FRAMES)
    pose[:, 0, 3], pose[:, 0, 5] = np.cos(yaw / 2), np.sin(yaw / 2)
    return MotionClip(fps=20.0, joints=np.stack([ja, jb], 1), rot6d=np.stack([ra, rb], 1), obj_pose=pose,
                      obj_type=np.array(["box"]), obj_size=np.array([[0.45, 0.35, 0.35]]),
                      phase=np.full((FRAMES, 3), 1 / 3), scenario="carry")


def test_npz_round_trip(clip, tmp_path):
    back = MotionClip.load(export_npz(clip, tmp_path / "m.npz"))
    np.testing.assert_allclose(back.joints, clip.joints)
    np.testing.assert_allclose(back.obj_pose, clip.obj_pose)
    assert back.scenario == "carry" and back.fps == clip.fps


def test_one_bvh_per_person_reads_back(clip, tmp_path):
    paths = export_bvh_dir(clip, tmp_path / "bvh")
    assert [p.name for p in paths] == ["person_A.bvh", "person_B.bvh"]
    for h, path in enumerate(paths):
        motion = read_bvh(path)
        assert motion.num_frames == FRAMES and motion.fps == 20.0
        pos = motion.global_positions()
        cols = [motion.index(name) for name in JOINT_NAMES]
        np.testing.assert_allclose(pos[:, cols], clip.joints[:, h], atol=1e-4)


def test_object_path_csv(clip, tmp_path):
    with export_object_path(clip, tmp_path / "obj.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0][:10] == ["frame", "time_s", "object", "x", "y", "z", "qw", "qx", "qy", "qz"]
    # The clip stores no anchors: the export carries the object type's grips along its pose.
    grips = local_to_world(np.broadcast_to(ObjectSpec(str(clip.obj_type[0]), tuple(clip.obj_size[0])).anchors,
                                           (FRAMES, 4, 3)), clip.obj_pose[:, 0].astype(float))
    assert rows[0][10:] == [f"anchor{k}_{a}" for k in range(4) for a in "xyz"]
    assert len(rows) == FRAMES + 1
    values = np.array([r[3:] for r in rows[1:]], float)
    np.testing.assert_allclose(values[:, :7], clip.obj_pose[:, 0], atol=1e-5)
    assert float(rows[-1][1]) == pytest.approx((FRAMES - 1) / 20.0)
    np.testing.assert_allclose(values[:, 7:].reshape(FRAMES, -1, 3), grips, atol=1e-5)


def read_glb(path):
    """-> (json dict, binary chunk bytes), checking the container layout on the way."""
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    json_len, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A and json_len % 4 == 0
    document = json.loads(data[20:20 + json_len])
    bin_len, bin_type = struct.unpack_from("<II", data, 20 + json_len)
    assert bin_type == 0x004E4942
    return document, data[28 + json_len:28 + json_len + bin_len]


def accessor_array(document, binary, index):
    acc = document["accessors"][index]
    view = document["bufferViews"][acc["bufferView"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc["type"]]
    dtype = np.float32 if acc["componentType"] == 5126 else np.uint32
    flat = np.frombuffer(binary, dtype, acc["count"] * width, view["byteOffset"])
    return flat.reshape(acc["count"], width)


def test_glb_is_an_animated_scene(clip, tmp_path):
    path = export_gltf(clip, tmp_path / "scene.glb")
    doc, binary = read_glb(path)
    assert len(doc["nodes"]) == 2 * 22 + 1
    assert doc["scenes"][0]["nodes"] == [0, 22, 44]
    assert doc["nodes"][JOINT_INDEX["l_wrist"]]["name"] == "A_l_wrist" and doc["nodes"][44]["name"] == "box"
    animation, = doc["animations"]
    # A rotation per joint, a translation per pelvis, translation + rotation for the box.
    assert len(animation["channels"]) == 2 * 22 + 2 + 2
    times = {s["input"] for s in animation["samplers"]}
    assert len(times) == 1
    t = accessor_array(doc, binary, times.pop())[:, 0]
    assert len(t) == FRAMES and t[-1] == pytest.approx((FRAMES - 1) / 20.0)
    for s in animation["samplers"]:
        assert doc["accessors"][s["output"]]["count"] == FRAMES

    # Play the animation back by forward kinematics over the node tree: it must be the clip.
    trans = np.array([[doc["nodes"][h * 22 + j]["translation"] for j in range(22)] for h in range(2)])
    rot = np.zeros((FRAMES, 2, 22, 3, 3))
    root = np.zeros((FRAMES, 2, 3))
    for ch in animation["channels"]:
        node, values = ch["target"]["node"], accessor_array(doc, binary, animation["samplers"][ch["sampler"]]["output"])
        if node >= 44:
            continue
        h, j = divmod(node, 22)
        if ch["target"]["path"] == "rotation":
            rot[:, h, j] = quat_to_matrix(np.roll(values.astype(float), 1, axis=-1))  # xyzw -> wxyz
        else:
            root[:, h] = values
    for h in range(2):
        assert [doc["nodes"][h * 22 + j].get("children", []) for j in range(22)] == \
            [[h * 22 + c for c, p in enumerate(PARENTS) if p == j] for j in range(22)]
        np.testing.assert_allclose(forward_kinematics(root[:, h], rot[:, h], trans[h]), clip.joints[:, h], atol=1e-4)
    box_rot = [accessor_array(doc, binary, animation["samplers"][ch["sampler"]]["output"])
               for ch in animation["channels"] if ch["target"] == {"node": 44, "path": "rotation"}][0]
    assert np.all(np.sum(box_rot[1:] * box_rot[:-1], axis=1) > 0)  # one hemisphere: short-arc playback


def test_trimesh_reads_the_glb_at_frame_zero(clip, tmp_path):
    import trimesh
    scene = trimesh.load(export_gltf(clip, tmp_path / "scene.glb"))
    assert isinstance(scene, trimesh.Scene) and len(scene.geometry) == 2 * 22 + 1
    for h, agent in enumerate("AB"):
        for name in ("l_wrist", "r_foot", "head"):
            transform, _ = scene.graph.get(f"{agent}_{name}")
            np.testing.assert_allclose(transform[:3, 3], clip.joints[0, h, JOINT_INDEX[name]], atol=1e-4)
    lo, hi = scene.bounds
    assert lo[1] > -0.1 and hi[1] < 2.0  # people stand on the ground, no stray geometry


def test_command_line_options_run_the_exports(clip, tmp_path):
    parser = argparse.ArgumentParser()
    add_export_arguments(parser)
    args = parser.parse_args(["--bvh-dir", str(tmp_path / "b"), "--npz", str(tmp_path / "m.npz"),
                              "--object-csv", str(tmp_path / "o.csv"), "--glb", str(tmp_path / "s.glb")])
    written = export_requested(clip, args)
    assert sorted(p.name for p in written) == ["m.npz", "o.csv", "person_A.bvh", "person_B.bvh", "s.glb"]
    assert all(p.exists() for p in written)
