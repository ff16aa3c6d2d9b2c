"""Exports: NPZ round trip, one BVH per person read back, the object path CSV, and the animated
glb (container layout, one armature and skinned body per person, animation accessors, forward
kinematics and skinning of the animation reproducing the clip, trimesh reading the static scene,
Blender importing it where Blender is installed)."""
import argparse
import csv
import json
import shutil
import subprocess
import struct

import numpy as np
import pytest

from engine.clip import MotionClip
from engine.export import (add_export_arguments, export_bvh_dir, export_gltf, export_npz, export_object_path,
                           export_requested)
from engine.geometry.rotations import axis_angle_to_matrix, matrix_to_6d, quat_to_matrix
from engine.io.bvh import read_bvh
from engine.objects import ObjectSpec, local_to_world
from engine.skeleton import JOINT_NAMES, PARENTS, REST_PELVIS_HEIGHT, forward_kinematics

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
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[acc["componentType"]]
    flat = np.frombuffer(binary, dtype, acc["count"] * width, view["byteOffset"])
    return flat.reshape(acc["count"], width)


def glb_playback(doc, binary, frame: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Play the glb back at a frame as a DCC tool does: joint world positions (H, 22, 3) by the
    node tree's animated transforms, and each body mesh's (vertices (V, 3) by linear blend
    skinning, the joint (V,) each is bound to)."""
    animation, = doc["animations"]
    local = {}
    for ch in animation["channels"]:
        value = accessor_array(doc, binary, animation["samplers"][ch["sampler"]]["output"])[frame].astype(float)
        local[ch["target"]["node"], ch["target"]["path"]] = value
    world = {}

    def transform(node, parent):
        m = np.eye(4)
        m[:3, :3] = quat_to_matrix(np.roll(local.get((node, "rotation"), doc["nodes"][node].get("rotation", [0, 0, 0, 1])), 1))
        m[:3, 3] = local.get((node, "translation"), doc["nodes"][node].get("translation", [0, 0, 0]))
        world[node] = parent @ m
        for child in doc["nodes"][node].get("children", []):
            transform(child, world[node])

    for root in doc["scenes"][0]["nodes"]:
        transform(root, np.eye(4))
    joints, bodies = [], []
    for skin in doc["skins"]:
        joints.append(np.array([world[j][:3, 3] for j in skin["joints"]]))
        bind = accessor_array(doc, binary, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
        body = next(node for node in doc["nodes"] if node.get("skin") == doc["skins"].index(skin))
        attributes = doc["meshes"][body["mesh"]]["primitives"][0]["attributes"]
        positions = accessor_array(doc, binary, attributes["POSITION"]).astype(float)
        bones = accessor_array(doc, binary, attributes["JOINTS_0"])[:, 0]
        assert np.all(accessor_array(doc, binary, attributes["WEIGHTS_0"]) == [1, 0, 0, 0])
        skinning = np.stack([world[j] @ bind[i] for i, j in enumerate(skin["joints"])])[bones]
        bodies.append((np.einsum("vij,vj->vi", skinning[:, :3, :3], positions) + skinning[:, :3, 3], bones))
    return np.stack(joints), bodies


def test_glb_is_one_rig_per_person_with_a_skinned_body(clip, tmp_path):
    path = export_gltf(clip, tmp_path / "scene.glb")
    doc, binary = read_glb(path)
    assert len(doc["nodes"]) == 2 * 24 + 1
    assert doc["scenes"][0]["nodes"] == [0, 23, 24, 47, 48]          # armatures, bodies, the box
    assert doc["scenes"][0]["extras"]["frame_end"] == FRAMES - 1
    assert [doc["nodes"][i]["name"] for i in (0, 23, 24, 48)] == ["A", "A_body", "B", "box"]
    for h, skin in enumerate(doc["skins"]):
        assert [doc["nodes"][j]["name"] for j in skin["joints"]] == list(JOINT_NAMES)   # as in the BVH
        assert [doc["nodes"][j].get("children", []) for j in skin["joints"]] == \
            [[skin["joints"][c] for c, p in enumerate(PARENTS) if p == j] for j in range(22)]
    animation, = doc["animations"]
    # A rotation per joint, a translation per pelvis, translation + rotation for the box.
    assert len(animation["channels"]) == 2 * 22 + 2 + 2
    times = {s["input"] for s in animation["samplers"]}
    assert len(times) == 1
    t = accessor_array(doc, binary, times.pop())[:, 0]
    assert len(t) == FRAMES and t[-1] == pytest.approx((FRAMES - 1) / 20.0)
    for s in animation["samplers"]:
        assert doc["accessors"][s["output"]]["count"] == FRAMES

    # Played back, the rig is the clip, and each body vertex keeps its place on its bone.
    reach = None
    for frame in (0, FRAMES // 2, FRAMES - 1):
        joints, bodies = glb_playback(doc, binary, frame)
        np.testing.assert_allclose(joints, clip.joints[frame], atol=1e-4)
        # a vertex's distance to its joint is the same in every frame, and within its bone
        distances = [np.linalg.norm(body - clip.joints[frame, h][bones], axis=1) for h, (body, bones) in enumerate(bodies)]
        reach = distances if reach is None else reach
        for d, d0, (_, bones) in zip(distances, reach, bodies):
            np.testing.assert_allclose(d, d0, atol=1e-4)
            assert d.max() < 0.6 and all(d[bones == j].min() < 0.15 for j in range(22))
    box_rot = [accessor_array(doc, binary, animation["samplers"][ch["sampler"]]["output"])
               for ch in animation["channels"] if ch["target"] == {"node": 48, "path": "rotation"}][0]
    assert np.all(np.sum(box_rot[1:] * box_rot[:-1], axis=1) > 0)  # one hemisphere: short-arc playback


def test_trimesh_reads_the_glb(clip, tmp_path):
    import trimesh
    scene = trimesh.load(export_gltf(clip, tmp_path / "scene.glb"))
    assert isinstance(scene, trimesh.Scene) and len(scene.geometry) == 2 + 1      # two bodies and the box
    lo, hi = scene.bounds
    assert lo[1] > -0.2 and hi[1] < 2.2                      # bodies in their rest pose, standing


def test_command_line_options_run_the_exports(clip, tmp_path):
    parser = argparse.ArgumentParser()
    add_export_arguments(parser)
    args = parser.parse_args(["--bvh-dir", str(tmp_path / "b"), "--npz", str(tmp_path / "m.npz"),
                              "--object-csv", str(tmp_path / "o.csv"), "--glb", str(tmp_path / "s.glb")])
    written = export_requested(clip, args)
    assert sorted(p.name for p in written) == ["m.npz", "o.csv", "person_A.bvh", "person_B.bvh", "s.glb"]
    assert all(p.exists() for p in written)


BLENDER_SCRIPT = '''
import bpy, json, sys
import numpy
if not hasattr(numpy, "bool"):   # Debian 12's Blender 3.4 glTF importer still uses an alias numpy 1.24 removed
    numpy.bool = bool
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps = 20            # the importer places keys at time * the scene's rate
bpy.ops.import_scene.gltf(filepath=sys.argv[-2])
armatures = [o for o in scene.objects if o.type == "ARMATURE"]
out = {"armatures": [a.name for a in armatures],
       "meshes": {o.name: [o.parent.name if o.parent else None, [m.type for m in o.modifiers]]
                  for o in scene.objects if o.type == "MESH"},
       "action_ranges": [list(a.frame_range) for a in bpy.data.actions],
       "frame_end": scene.get("frame_end"), "positions": {}}
for frame in (0, 13, 29):
    scene.frame_set(frame)
    out["positions"][frame] = [{b.name: list(a.matrix_world @ b.head) for b in a.pose.bones} for a in armatures]
json.dump(out, open(sys.argv[-1], "w"))
'''


@pytest.mark.skipif(shutil.which("blender") is None,
                    reason="Blender is not installed (apt-get install blender python3-numpy to run this check)")
def test_blender_imports_one_armature_per_person_playing_the_clip(clip, tmp_path):
    (tmp_path / "read.py").write_text(BLENDER_SCRIPT)
    glb, result = export_gltf(clip, tmp_path / "scene.glb"), tmp_path / "blender.json"
    subprocess.run(["blender", "-b", "--factory-startup", "--python", str(tmp_path / "read.py"), "--", str(glb), str(result)],
                   check=True, capture_output=True, timeout=300)
    out = json.loads(result.read_text())
    assert out["armatures"] == ["A", "B"]
    assert out["meshes"] == {"A_body": ["A", ["ARMATURE"]], "B_body": ["B", ["ARMATURE"]], "box": [None, []]}
    assert all(r == [0, FRAMES - 1] for r in out["action_ranges"]) and out["frame_end"] == FRAMES - 1
    for frame, people in out["positions"].items():
        for h, bones in enumerate(people):
            assert sorted(bones) == sorted(JOINT_NAMES)
            blender = np.array([bones[name] for name in JOINT_NAMES])           # Blender is Z up
            np.testing.assert_allclose(blender[:, [0, 2, 1]] * (1, 1, -1), clip.joints[int(frame), h], atol=1e-4)
