"""engine.io: BVH reading and writing, retargeting, InterHuman and CORE4D layouts, import-bvh CLI."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.cli import main as cli_main
from engine.clip import MotionClip
from engine.geometry.rotations import axis_angle_to_matrix, quat_to_matrix, sixd_to_matrix
from engine.io import (CMU_SALSA_MAP, SMPL22_MAP, BvhError, ImportConfig, JointMap, RetargetError, clip_to_bvh,
                       format_bvh, import_bvh, parse_bvh, read_bvh, write_bvh)
from engine.io.core4d import list_core4d, load_core4d
from engine.io.interhuman import ZUP_TO_OURS, list_interhuman, load_interhuman
from engine.io.resample import resample_linear, resample_quaternions
from engine.io.retarget import TEMPLATE_LEG_LENGTH, leg_length
from engine.skeleton import FEET, NUM_JOINTS, REST_OFFSETS, bone_lengths, forward_kinematics
from engine.skeleton import JOINT_INDEX as J


def _find_salsa() -> Path | None:
    """../shared/data/cmu_salsa beside the checkout (the repo may sit at any depth under it)."""
    for base in Path(__file__).resolve().parents:
        cand = base / "shared" / "data" / "cmu_salsa"
        if cand.is_dir():
            return cand
    return None


SALSA = _find_salsa()
needs_salsa = pytest.mark.skipif(SALSA is None, reason="../shared/data/cmu_salsa is not available")


def rot(axis: str, deg: float) -> np.ndarray:
    """Elementary rotation matrix, written out by hand (independent of engine.rotations)."""
    c, s = np.cos(np.deg2rad(deg)), np.sin(np.deg2rad(deg))
    return {"X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def walking_joints(n: int, fps: float, offsets: np.ndarray = REST_OFFSETS) -> np.ndarray:
    """(n, 22, 3) a template person walking along +Z (facing +Z), feet near the ground."""
    t = np.arange(n) / fps
    local = np.broadcast_to(np.eye(3), (n, NUM_JOINTS, 3, 3)).copy()
    swing = 0.4 * np.sin(2 * np.pi * t)
    x = np.array([1.0, 0, 0])
    local[:, J["l_hip"]] = axis_angle_to_matrix(x * swing[:, None])
    local[:, J["r_hip"]] = axis_angle_to_matrix(-x * swing[:, None])
    local[:, J["l_knee"]] = axis_angle_to_matrix(x * (0.3 + 0.3 * np.sin(2 * np.pi * t))[:, None])
    local[:, J["l_shoulder"]] = axis_angle_to_matrix(np.array([0, 0, -1.2]) * np.ones((n, 1)))
    local[:, J["r_shoulder"]] = axis_angle_to_matrix(np.array([0, 0, 1.2]) * np.ones((n, 1)))
    local[:, J["spine1"]] = axis_angle_to_matrix(np.array([0, 1.0, 0]) * 0.2 * np.sin(2 * np.pi * t)[:, None])
    root = np.stack([np.zeros(n), 0.95 - 0.02 * np.cos(4 * np.pi * t), 1.2 * t], -1)
    return forward_kinematics(root, local, offsets)


# ------------------------------------------------------------------------------------------ parser

TINY = """HIERARCHY\r
ROOT Hips\r
{\r
\tOFFSET 0 0 0\r
  CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation\r
\tJOINT Chest {\r
\t\tOFFSET   0.0  1.0  0.0\r
\t\tCHANNELS 3 Zrotation Xrotation Yrotation\r
\t\tEnd Site\r
\t\t{\r
\t\t\tOFFSET 0 0 1\r
\t\t}\r
\t}\r
\tJOINT Leg\r
\t{\r
\t\tOFFSET 1 0 0\r
\t\tCHANNELS 6 Zrotation Xposition Yposition Zposition Xrotation Yrotation\r
\t\tEnd Site { OFFSET 0 -1 0 }\r
\t}\r
}\r
MOTION\r
Frames:    2\r
Frame Time:\t0.5\r
\r
1 2 3 0 0 0   0 0 0   0 5 6 7 0 0\r
1 2 3 90 0 0   90 90 0   90 5 6 7 90 0\r
\r
"""


def test_parser_reads_hierarchy_channels_and_end_sites():
    m = parse_bvh(TINY)
    assert m.names == ["Hips", "Chest", "Chest/End Site", "Leg", "Leg/End Site"]
    assert [n.parent for n in m.nodes] == [-1, 0, 1, 0, 3]
    assert m.nodes[3].channels == ("Zrotation", "Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation")
    assert m.nodes[2].is_end_site and not m.nodes[1].is_end_site
    assert m.data.shape == (2, 15) and m.fps == 2.0


def test_parser_fk_matches_hand_computation():
    p = parse_bvh(TINY).global_positions()                      # (2, 5, 3)
    # Frame 0: no rotation; Leg's position channels replace its OFFSET.
    np.testing.assert_allclose(p[0], [[1, 2, 3], [1, 3, 3], [1, 3, 4], [6, 8, 10], [6, 7, 10]], atol=1e-12)
    # Frame 1: root Y90 (listed order Y X Z), Chest Z90 then X90, Leg Z90 then X90 (positions between).
    R_root = rot("Y", 90)
    R_chest = R_root @ rot("Z", 90) @ rot("X", 90)
    R_leg = R_root @ rot("Z", 90) @ rot("X", 90)
    chest = np.array([1, 2, 3]) + R_root @ [0, 1, 0]
    leg = np.array([1, 2, 3]) + R_root @ [5, 6, 7]
    expect = [[1, 2, 3], chest, chest + R_chest @ [0, 0, 1], leg, leg + R_leg @ [0, -1, 0]]
    np.testing.assert_allclose(p[1], expect, atol=1e-12)


def test_parser_handles_deep_hierarchies():
    depth = 1500  # deeper than Python's recursion limit: the parser must not recurse
    lines = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0", "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for k in range(1, depth):
        lines += [f"JOINT j{k}", "{", "OFFSET 0 0.001 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", "OFFSET 0 0.001 0", "}"] + ["}"] * depth
    lines += ["MOTION", "Frames: 1", "Frame Time: 0.1", " ".join(["0"] * (6 + 3 * (depth - 1)))]
    p = parse_bvh("\n".join(lines)).global_positions()
    assert p.shape == (1, depth + 1, 3)
    assert p[0, -1, 1] == pytest.approx(depth * 0.001)


@pytest.mark.parametrize("text, line, words", [
    ("ROOT a\n{\n}", 1, "HIERARCHY"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 x\n}\nMOTION\nFrames: 0\nFrame Time: 0.1\n", 4, "number"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Wrotation\n}\nMOTION\nFrames: 0\nFrame Time: 0.1\n", 5, "channel"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\nBOGUS\n}\n", 6, "BOGUS"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n", 5, "end of the hierarchy"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\n", 6, "MOTION"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\nMOTION\nFrame Time: 0.1\n", 8, "Frames"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0\n1\n", 9, "frame time"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 2 Xrotation Yrotation\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n1 2\n3\n", 11, "2 channel values"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\nMOTION\nFrames: 3\nFrame Time: 0.1\n1\n2\n", 11, "3 frames"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n1\nfoo\n", 11, "non-numeric"),
])
def test_parser_errors_name_the_line(text, line, words):
    with pytest.raises(BvhError) as info:
        parse_bvh(text, "bad.bvh")
    msg = str(info.value)
    assert isinstance(info.value, ValueError) and "\n" not in msg
    assert msg.startswith(f"bad.bvh: line {line}:") and words in msg, msg


def test_read_bvh_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_bvh(tmp_path / "nope.bvh")


# ---------------------------------------------------------------------------------------- resample

def test_resample_linear_and_slerp():
    x = np.arange(13, dtype=float)[:, None] * [1.0, 2.0]         # 13 frames at 120 fps = 0.1 s
    y = resample_linear(x, 120, 50)                             # frames at 0, 0.02, ..., 0.1 s
    np.testing.assert_allclose(y[:, 0], np.arange(6) * 2.4)
    q = np.array([[1.0, 0, 0, 0], [np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0]])  # 0 and 90 deg about Y
    mid = resample_quaternions(q, 1.0, 2.0)
    assert mid.shape == (3, 4)
    np.testing.assert_allclose(quat_to_matrix(mid[1]), rot("Y", 45), atol=1e-12)


# ------------------------------------------------------------------------------ retargeting (tiny)

def cmu_like_bvh(path: Path, scale: float = 0.78, fps: float = 120.0, seconds: float = 1.0,
                 names: dict | None = None) -> None:
    """Write a BVH with CMU node names (plus an extra leaf) whose motion is walking_joints."""
    n = int(seconds * fps) + 1
    clip = MotionClip.from_joints(walking_joints(n, fps)[:, None], fps)
    motion = clip_to_bvh(clip, 0, order="ZXY")
    rename = {"pelvis": "hip", "spine1": "abdomen", "spine2": "chest", "spine3": "chest2", "neck": "neck",
              "head": "head", "l_hip": "lThigh", "l_knee": "lShin", "l_ankle": "lFoot", "l_foot": "lToe",
              "r_hip": "rThigh", "r_knee": "rShin", "r_ankle": "rFoot", "r_foot": "rToe",
              "l_collar": "lCollar", "l_shoulder": "lShldr", "l_elbow": "lForeArm", "l_wrist": "lHand",
              "r_collar": "rCollar", "r_shoulder": "rShldr", "r_elbow": "rForeArm", "r_wrist": "rHand"}
    rename.update(names or {})
    for node in motion.nodes:
        base, _, rest = node.name.partition("/")
        node.name = rename[base] + ("/" + rest if rest else "")
        node.offset = node.offset * scale
    motion.data[:, :3] *= scale
    path.write_text(format_bvh(motion))


def tiny_map(**changes) -> JointMap:
    d = CMU_SALSA_MAP.to_dict()
    d["joints"].update({"pelvis": "hip", "spine3": "chest2", "l_foot": "lToe", "r_foot": "rToe"}, **changes)
    return JointMap.from_dict(d)


def test_import_tiny_bvh_rescales_floors_and_fits(tmp_path):
    cmu_like_bvh(tmp_path / "a.bvh")
    clip, report = import_bvh([tmp_path / "a.bvh"], ImportConfig(fps=20), tiny_map())
    assert clip.num_humans == 1 and clip.num_frames == 21 and clip.fps == 20
    expected_scale = TEMPLATE_LEG_LENGTH / leg_length(walking_joints(21, 20) * 0.78)
    assert report.source_fps == 120 and report.scale == pytest.approx(expected_scale, rel=1e-3)
    assert 1.2 < report.scale < 1.35
    assert report.fk_error < 1e-3 and report.bone_drift < 1e-4
    lowest = clip.joints[:, 0, list(FEET), 1].min(axis=1)
    assert np.percentile(lowest, 5) == pytest.approx(0.0, abs=1e-4)
    assert 0.85 < report.pelvis_height[0] < 1.0
    assert np.all(clip.joints[:, 0, J["l_hip"], 0] > clip.joints[:, 0, J["r_hip"], 0])  # facing +Z
    travelled = clip.joints[-1, 0, 0, 2] - clip.joints[0, 0, 0, 2]
    assert travelled == pytest.approx(1.2 * 0.78 * report.scale, rel=1e-4)  # the world scales with the body


def test_import_keeps_one_scale_for_two_people(tmp_path):
    cmu_like_bvh(tmp_path / "a.bvh", scale=0.78)
    cmu_like_bvh(tmp_path / "b.bvh", scale=0.70)
    clip, report = import_bvh([tmp_path / "a.bvh", tmp_path / "b.bvh"], ImportConfig(fps=30), tiny_map())
    legs = np.median(bone_lengths(clip.joints)[..., J["l_knee"]], axis=0)
    assert legs[0] / legs[1] == pytest.approx(0.78 / 0.70, rel=1e-3)  # proportions kept, one factor
    assert clip.num_frames == 31


def test_joint_map_json_midpoint_and_errors(tmp_path):
    cmu_like_bvh(tmp_path / "a.bvh")
    d = tiny_map(spine3={"midpoint": ["chest", "neck"]}).to_dict()
    (tmp_path / "map.json").write_text(json.dumps(d))
    m = JointMap.load(tmp_path / "map.json")
    assert m.sources["spine3"] == ("chest", "neck")
    motion = read_bvh(tmp_path / "a.bvh")
    p = motion.global_positions()
    j = m.apply(motion.names, p)
    np.testing.assert_allclose(j[:, J["spine3"]], (p[:, motion.index("chest")] + p[:, motion.index("neck")]) / 2)
    with pytest.raises(RetargetError, match="nodes not in the file: nope"):
        tiny_map(head="nope").apply(motion.names, p)
    bad = dict(d, joints={k: v for k, v in d["joints"].items() if k != "head"})
    with pytest.raises(RetargetError, match="missing joints"):
        JointMap.from_dict(bad)
    with pytest.raises(RetargetError, match="rotation"):
        JointMap.from_dict(dict(d, to_world=np.diag([-1.0, 1, 1]).tolist()))


def test_import_rejects_mirrored_and_upside_down(tmp_path):
    cmu_like_bvh(tmp_path / "a.bvh")
    swapped = {}
    for ours, src in tiny_map().sources.items():
        other = ours.replace("l_", "#").replace("r_", "l_").replace("#", "r_")
        swapped[other] = src[0]
    with pytest.raises(RetargetError, match="mirrored"):
        import_bvh([tmp_path / "a.bvh"], ImportConfig(), JointMap("swapped", {k: (v,) for k, v in swapped.items()}))
    flipped = tiny_map().to_dict()
    flipped["to_world"] = np.diag([1.0, -1, -1]).tolist()
    with pytest.raises(RetargetError, match="up axis"):
        import_bvh([tmp_path / "a.bvh"], ImportConfig(), JointMap.from_dict(flipped))


def test_import_rejects_unsynchronized_pair(tmp_path):
    cmu_like_bvh(tmp_path / "a.bvh", seconds=1.0)
    cmu_like_bvh(tmp_path / "b.bvh", seconds=0.5)
    with pytest.raises(RetargetError, match="does not match"):
        import_bvh([tmp_path / "a.bvh", tmp_path / "b.bvh"], ImportConfig(), tiny_map())


# ------------------------------------------------------------------------------------------ writer

def synthetic_clip(fps: float = 30.0, n: int = 31) -> MotionClip:
    people = np.stack([walking_joints(n, fps), walking_joints(n, fps) + [1.5, 0, 0.3]], 1)
    return MotionClip.from_joints(people, fps)


def clip_fk(clip: MotionClip, h: int) -> np.ndarray:
    return forward_kinematics(clip.joints[:, h, 0].astype(np.float64),
                              sixd_to_matrix(clip.rot6d[:, h].astype(np.float64)), clip.offsets()[h])


@pytest.mark.parametrize("order", ["ZYX", "ZXY", "XYZ"])
def test_bvh_export_round_trip(tmp_path, order):
    clip = synthetic_clip()
    write_bvh(clip, 1, tmp_path / "p1.bvh", order=order)
    motion = read_bvh(tmp_path / "p1.bvh")
    assert motion.num_frames == clip.num_frames and motion.fps == pytest.approx(30.0)
    assert motion.nodes[1].channels == tuple(f"{a}rotation" for a in order)
    back, report = import_bvh([tmp_path / "p1.bvh"], ImportConfig(fps=30, rescale=False, floor=False), SMPL22_MAP)
    assert np.max(np.abs(back.joints[:, 0] - clip_fk(clip, 1))) < 1e-3
    np.testing.assert_allclose(back.bone_offsets[0], clip.offsets()[1], atol=1e-4)


def test_bvh_export_read_by_bvhio(tmp_path):
    bvhio = pytest.importorskip("bvhio")
    clip = synthetic_clip()
    write_bvh(clip, 0, tmp_path / "p0.bvh")
    expect = clip_fk(clip, 0)
    root = bvhio.readAsHierarchy(str(tmp_path / "p0.bvh"))
    for frame in (0, 15, 30):
        root.loadPose(frame)
        got = {joint.Name: np.array(joint.PositionWorld) for joint, _, _ in root.layout()}
        assert len(got) == NUM_JOINTS
        for name, j in J.items():
            np.testing.assert_allclose(got[name], expect[frame, j], atol=1e-4)


# ---------------------------------------------------------------------------------- dataset layouts

def test_interhuman_layout(tmp_path):
    fps, n = 30.0, 31
    ours = np.stack([walking_joints(n, fps), walking_joints(n, fps)[:, :, [0, 1, 2]] * [-1, 1, -1] + [0, 0, 2]], 1)
    for h, who in enumerate(("person1", "person2")):
        row = np.zeros((n, 492), np.float32)
        row[:, :66] = (ours[:, h] @ ZUP_TO_OURS).reshape(n, 66)      # into their Z-up frame
        (tmp_path / "motions_processed" / who).mkdir(parents=True)
        np.save(tmp_path / "motions_processed" / who / "1234.npy", row)
    (tmp_path / "annots").mkdir()
    (tmp_path / "annots" / "1234.txt").write_text("two people walk\nthey pass\nwalking past\n")
    (tmp_path / "split").mkdir()
    (tmp_path / "split" / "train.txt").write_text("1234\n")
    assert list_interhuman(tmp_path) == ["1234"] and list_interhuman(tmp_path, "train") == ["1234"]
    sample = load_interhuman(tmp_path, "1234")
    clip = sample.clip
    assert clip.num_humans == 2 and clip.fps == 20 and clip.num_frames == 21
    assert sample.texts[0] == "two people walk" and sample.report.fk_error < 1e-3
    expect = ours[::3].copy()                         # 30 -> 20 fps: every 3rd input is every 2nd output
    expect[..., 1] -= sample.report.floors[None, :, None]
    np.testing.assert_allclose(clip.joints[::2], expect, atol=2e-4)  # float32 file precision
    assert np.all(clip.joints[:, 1, J["l_hip"], 0] < clip.joints[:, 1, J["r_hip"], 0])  # person 2 faces -Z


def test_core4d_layout(tmp_path):
    fps, n = 15.0, 16
    zup = np.linalg.inv(ZUP_TO_OURS)      # our frame -> a Z-up world
    people = [walking_joints(n, fps), walking_joints(n, fps) + [1.0, 0, 0]]
    seq = tmp_path / "human_object_motions" / "20231002" / "004"
    seq.mkdir(parents=True)
    for h, who in enumerate(("person1", "person2")):
        joints = np.concatenate([people[h] @ zup.T, np.zeros((n, 105, 3))], axis=1).astype(np.float32)
        np.savez(seq / f"{who}_poses.npz", {"joints": joints, "betas": np.zeros((n, 10), np.float32)})
    pose = np.tile(np.eye(4), (n, 1, 1))
    pose[:, :3, 3] = (np.array([0.5, 0.4, 1.0]) @ zup.T)    # a box held 0.4 m up, 1 m ahead
    pose[:, :3, :3] = zup @ rot("Y", 30)
    np.save(seq / "object_poses_box007.npy", pose)
    model = tmp_path / "object_models" / "box" / "box007_m.obj"
    model.parent.mkdir(parents=True)
    model.write_text("".join(f"v {x} {y} {z}\n" for x in (-0.3, 0.3) for y in (-0.2, 0.2) for z in (-0.1, 0.1)))
    assert list_core4d(tmp_path) == ["20231002/004"]
    sample = load_core4d(tmp_path, "20231002/004")
    clip = sample.clip
    assert clip.num_humans == 2 and clip.num_objects == 1 and clip.num_frames == 21
    assert sample.object_names == ["box007"] and clip.obj_type[0] == "box"
    np.testing.assert_allclose(clip.obj_size[0], [0.6, 0.4, 0.2], atol=1e-6)
    floor = sample.report.floors.mean()
    np.testing.assert_allclose(clip.obj_pose[:, 0, :3], np.tile([0.5, 0.4 - floor, 1.0], (21, 1)), atol=1e-5)
    np.testing.assert_allclose(quat_to_matrix(clip.obj_pose[0, 0, 3:]), rot("Y", 30), atol=1e-5)
    assert np.all(clip.joints[:, :, J["l_hip"], 0] > clip.joints[:, :, J["r_hip"], 0])
    np.testing.assert_allclose(clip.joints[::4, 0, J["pelvis"], 2], people[0][::3, 0, 2], atol=1e-5)


# ------------------------------------------------------------------------------ CMU salsa (shared)

def facing_plus_z(joints: np.ndarray) -> np.ndarray:
    """(N, H) mask of frames where the feet (ankle -> toe) point within ~45 degrees of +Z."""
    fwd = sum(joints[..., toe, :] - joints[..., ankle, :] for toe, ankle in ((J["l_foot"], J["l_ankle"]), (J["r_foot"], J["r_ankle"])))
    return fwd[..., 2] > 0.7 * np.linalg.norm(fwd[..., [0, 2]], axis=-1)


@needs_salsa
@pytest.mark.parametrize("take", ["01", "02", "03", "04", "05", "06", "07", "09", "10"])
def test_cmu_salsa_pair(take):
    clip, report = import_bvh([SALSA / f"60_{take}.bvh", SALSA / f"61_{take}.bvh"], ImportConfig(fps=20))
    j = clip.joints.astype(np.float64)
    assert clip.num_humans == 2 and clip.fps == 20
    assert 1.2 < report.scale < 1.35
    lengths = bone_lengths(j)
    assert np.max(lengths.max(axis=0) - lengths.min(axis=0)) < 1e-3
    assert report.fk_error < 0.01
    pelvis = j[:, :, J["pelvis"], 1].mean(axis=0)
    assert np.all((0.8 < pelvis) & (pelvis < 1.0)), pelvis
    lowest = j[:, :, list(FEET), 1].min(axis=2)
    assert np.all(np.abs(np.percentile(lowest, 5, axis=0)) < 0.01)
    assert np.all(np.median(lowest, axis=0) < 0.05)
    facing = facing_plus_z(j)
    left_is_plus_x = j[..., J["l_hip"], 0] > j[..., J["r_hip"], 0]
    assert facing.sum() > 20 and np.mean(left_is_plus_x[facing]) > 0.95
    assert np.mean(j[..., J["head"], 1] > j[..., J["pelvis"], 1]) > 0.99  # 09 ends bending to a shoe
    # Partners stay apart at a real distance (one scale): pelvis spacing mostly 0.3-2 m.
    gap = np.linalg.norm(j[:, 0, 0, [0, 2]] - j[:, 1, 0, [0, 2]], axis=-1)
    assert 0.3 < np.median(gap) < 2.0


@needs_salsa
def test_cli_import_bvh(tmp_path, capsys):
    out = tmp_path / "salsa10.npz"
    assert cli_main(["import-bvh", str(SALSA / "60_10.bvh"), str(SALSA / "61_10.bvh"), "-o", str(out), "--fps", "30"]) == 0
    clip = MotionClip.load(out)
    assert clip.num_humans == 2 and clip.fps == 30 and clip.bone_offsets.shape == (2, 22, 3)
    assert "2 people" in capsys.readouterr().out


def test_cli_import_bvh_errors(tmp_path, capsys):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT a\n{\nOFFSET 0 0 q\n}\n")
    assert cli_main(["import-bvh", str(bad), "-o", str(tmp_path / "x.npz")]) == 2
    assert "line 4" in capsys.readouterr().err
    cmu_like_bvh(tmp_path / "a.bvh")
    assert cli_main(["import-bvh", str(tmp_path / "a.bvh"), "-o", str(tmp_path / "x.npz")]) == 2  # cmu map: no lToe
    assert "nodes not in the file" in capsys.readouterr().err
    (tmp_path / "map.json").write_text(json.dumps(tiny_map().to_dict()))
    assert cli_main(["import-bvh", str(tmp_path / "a.bvh"), "-o", str(tmp_path / "x.npz"), "--map", str(tmp_path / "map.json")]) == 0
    assert cli_main(["import-bvh", str(tmp_path / "a.bvh"), "-o", str(tmp_path / "x.npz"), "--map", "nope"]) == 2
