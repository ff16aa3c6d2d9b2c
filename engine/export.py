"""Motion out of the program: one function per file format, each taking a MotionClip.

- `export_npz`: the clip itself (engine/clip.py format).
- `export_bvh_dir`: one BVH per person, written by engine/io/bvh_export.py.
- `export_object_path`: each object's root pose and anchors per frame, as CSV.
- `export_gltf`: an animated binary glTF (.glb) for Blender and other DCC tools.

The glb is written here with numpy + json + struct (glTF 2.0 is Y up, metres, right-handed:
the same world as ours, so no axis change). Each person is a rig, as DCC tools import one: an
armature node (named by agent: A, B, ...) over the 22-joint node hierarchy, bones named as in the
BVH (skeleton.JOINT_NAMES) with the rest offsets as translations, and a skin that binds one body
mesh (a capsule per bone, a sphere on each leaf joint; each vertex rigidly on its bone) in the
rest pose (every local rotation identity, as in the BVH). One animation drives every joint's
local rotation (quaternions from rot6d) and the pelvis translation, plus each object's
translation and rotation; objects are nodes of their own, named by type. The nodes' static
transforms are frame 0, so viewers that ignore animation show frame 0; the scene's extras give
the clip's frame range and rate.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import struct
from pathlib import Path

import numpy as np

from .atomic import OutputPathError, check_output_path, write_bytes, write_text
from .body import JOINT_RADII
from .clip import MotionClip
from .geometry.rotations import matrix_to_quat, rotation_between, sixd_to_matrix
from .io.bvh_export import write_bvh
from .objects import DEFAULT_SIZES, ObjectSpec, local_to_world
from .skeleton import CHILDREN, JOINT_NAMES, NUM_JOINTS, PARENTS, rest_pose
from .storyboard import AGENT_COLORS

# glTF constants (glTF 2.0 specification, section 5).
_FLOAT, _UINT16, _UINT32 = 5126, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
_TYPES = {1: "SCALAR", 3: "VEC3", 4: "VEC4", 16: "MAT4"}
_COMPONENTS = {np.dtype(np.float32): _FLOAT, np.dtype(np.uint16): _UINT16, np.dtype(np.uint32): _UINT32}

BONE_RADIUS_SHARE = 0.8  # capsule radius as a share of the thinner end's collision radius
OBJECT_COLOR = (0.6, 0.6, 0.62, 1.0)


def agent_names(count: int) -> list[str]:
    """'A', 'B', ...: the agent ids sketchify and the app give people, in clip order."""
    return [chr(ord("A") + h) for h in range(count)]


# ---- NPZ and BVH ------------------------------------------------------------------------------

def export_npz(clip: MotionClip, path: str | Path) -> Path:
    path = Path(path)
    clip.save(path)
    return path


def export_bvh_dir(clip: MotionClip, directory: str | Path, stem: str = "person") -> list[Path]:
    """One BVH per person, `<directory>/<stem>_<agent>.bvh` (agents A, B, ...); the directory
    is created when missing. Returns the written paths in person order."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for h, name in enumerate(agent_names(clip.num_humans)):
        path = directory / f"{stem}_{name}.bvh"
        write_bvh(clip, h, path)
        paths.append(path)
    return paths


# ---- object path CSV ----------------------------------------------------------------------------

def object_specs(clip: MotionClip) -> list[ObjectSpec]:
    """The clip's objects as ObjectSpecs (type and size; the type's default anchors)."""
    specs = []
    for o in range(clip.num_objects):
        kind = str(clip.obj_type[o]) if clip.obj_type is not None else "box"
        size = tuple(clip.obj_size[o]) if clip.obj_size is not None else DEFAULT_SIZES[kind]
        specs.append(ObjectSpec(kind, size))
    return specs


def world_anchors(clip: MotionClip) -> np.ndarray:
    """(N, O, K, 3): the clip's anchors, else each type's default anchors carried by the pose."""
    if clip.obj_anchors is not None:
        return np.asarray(clip.obj_anchors, float)
    return np.stack([local_to_world(spec.anchors[None], clip.obj_pose[:, o].astype(float))
                     for o, spec in enumerate(object_specs(clip))], axis=1)


def export_object_path(clip: MotionClip, path: str | Path) -> Path:
    """CSV with a header row and one row per frame and object:
    frame, time_s, object, x, y, z, qw, qx, qy, qz, anchor0_x, anchor0_y, anchor0_z, ...
    `object` is the object's id (its type, with _2, _3 ... for repeats, as in storyboards)."""
    if clip.num_objects == 0:
        raise ValueError("the clip has no object, so there is no object path to export")
    anchors = world_anchors(clip)                                        # (N, O, K, 3)
    ids = _object_ids(object_specs(clip))
    header = ["frame", "time_s", "object", "x", "y", "z", "qw", "qx", "qy", "qz"]
    header += [f"anchor{k}_{axis}" for k in range(anchors.shape[2]) for axis in "xyz"]
    path = Path(path)
    text = io.StringIO(newline="")
    writer = csv.writer(text)
    writer.writerow(header)
    for n in range(clip.num_frames):
        for o, oid in enumerate(ids):
            values = list(clip.obj_pose[n, o]) + list(anchors[n, o].reshape(-1))
            writer.writerow([n, f"{n / clip.fps:.6f}", oid] + [f"{v:.6f}" for v in values])
    write_text(path, text.getvalue())
    return path


def _object_ids(specs: list[ObjectSpec]) -> list[str]:
    ids = []
    for i, spec in enumerate(specs):
        same = sum(s.type == spec.type for s in specs[:i])
        ids.append(spec.type if same == 0 else f"{spec.type}_{same + 1}")
    return ids


# ---- glTF ---------------------------------------------------------------------------------------

class _GlbBuffer:
    """Accumulates the binary chunk: one 4-byte aligned bufferView and accessor per array."""

    def __init__(self):
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, target: int | None = None, bounds: bool = False) -> int:
        """array: (count,) or (count, 1|3|4|16), float32, uint16 or uint32. Returns the accessor index."""
        array = np.ascontiguousarray(array)
        width = 1 if array.ndim == 1 else array.shape[1]
        self.data += b"\0" * (-len(self.data) % 4)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        self.data += array.tobytes()
        self.views.append(view)
        accessor = {"bufferView": len(self.views) - 1, "componentType": _COMPONENTS[array.dtype],
                    "count": int(array.shape[0]), "type": _TYPES[width]}
        if bounds:  # required for POSITION attributes and animation inputs
            flat = array.reshape(len(array), width)
            accessor["min"] = flat.min(axis=0).tolist()
            accessor["max"] = flat.max(axis=0).tolist()
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def _joint_mesh(offsets: np.ndarray, j: int):
    """trimesh of joint j's bones in j's local frame: a capsule to each child, or a sphere on a
    leaf. offsets: (22, 3) the person's bone offsets."""
    import trimesh
    parts = []
    for c in CHILDREN[j]:
        length = float(np.linalg.norm(offsets[c]))
        radius = BONE_RADIUS_SHARE * min(JOINT_RADII[j], JOINT_RADII[c])
        capsule = trimesh.creation.capsule(height=length, radius=radius, count=[8, 8])
        transform = np.eye(4)
        transform[:3, :3] = rotation_between(np.array([0.0, 0.0, 1.0]), offsets[c])  # capsule axis is +Z
        transform[:3, 3] = offsets[c] / 2
        capsule.apply_transform(transform)
        parts.append(capsule)
    if not parts:
        parts.append(trimesh.creation.icosphere(subdivisions=1, radius=float(JOINT_RADII[j])))
    return trimesh.util.concatenate(parts)


def _add_mesh(buf: _GlbBuffer, meshes: list[dict], mesh, material: int, bones: np.ndarray | None = None) -> int:
    """A trimesh as a glTF mesh; with `bones` (V,) each vertex is skinned wholly to that joint."""
    attributes = {"POSITION": buf.add(np.asarray(mesh.vertices, np.float32), _ARRAY_BUFFER, bounds=True),
                  "NORMAL": buf.add(np.asarray(mesh.vertex_normals, np.float32), _ARRAY_BUFFER)}
    if bones is not None:
        joints = np.zeros((len(bones), 4), np.uint16)
        joints[:, 0] = bones
        weights = np.zeros((len(bones), 4), np.float32)
        weights[:, 0] = 1.0
        attributes.update(JOINTS_0=buf.add(joints, _ARRAY_BUFFER), WEIGHTS_0=buf.add(weights, _ARRAY_BUFFER))
    indices = buf.add(np.asarray(mesh.faces, np.uint32).reshape(-1), _ELEMENT_ARRAY_BUFFER)
    meshes.append({"primitives": [{"attributes": attributes, "indices": indices, "material": material}]})
    return len(meshes) - 1


def _body_mesh(offsets: np.ndarray) -> tuple[object, np.ndarray, np.ndarray]:
    """(trimesh of the whole body in the rest pose, (V,) joint of each vertex, (22, 3) rest joint
    positions) for a person with bone offsets (22, 3)."""
    import trimesh
    rest = rest_pose(offsets)
    parts = [_joint_mesh(offsets, j) for j in range(NUM_JOINTS)]
    for j, part in enumerate(parts):
        part.apply_translation(rest[j])
    bones = np.concatenate([np.full(len(part.vertices), j) for j, part in enumerate(parts)])
    return trimesh.util.concatenate(parts), bones, rest


def _continuous(quat_xyzw: np.ndarray) -> np.ndarray:
    """Flip signs so consecutive quaternions (N, 4) lie in one hemisphere: viewers then
    interpolate along the short arc."""
    q = quat_xyzw.copy()
    for n in range(1, len(q)):
        if np.dot(q[n], q[n - 1]) < 0:
            q[n] = -q[n]
    return q


def _hex_rgba(color: str) -> list[float]:
    return [int(color[i:i + 2], 16) / 255 for i in (1, 3, 5)] + [1.0]


def gltf_document(clip: MotionClip) -> tuple[dict, bytes]:
    """The glTF JSON (dict) and binary buffer of the animated scene (see the module docstring).
    Nodes: person h is nodes h * 24 + (0: armature, 1 + j: joint j, 23: body), then the objects."""
    buf = _GlbBuffer()
    n, num_humans = clip.num_frames, clip.num_humans
    names = agent_names(num_humans)
    materials = [{"name": f"person_{name}", "pbrMetallicRoughness": {
        "baseColorFactor": _hex_rgba(AGENT_COLORS[h % len(AGENT_COLORS)]), "metallicFactor": 0.0,
        "roughnessFactor": 0.8}} for h, name in enumerate(names)]
    materials.append({"name": "object", "pbrMetallicRoughness": {
        "baseColorFactor": list(OBJECT_COLOR), "metallicFactor": 0.0, "roughnessFactor": 0.6}})
    meshes: list[dict] = []
    nodes: list[dict] = []
    skins: list[dict] = []
    samplers: list[dict] = []
    channels: list[dict] = []
    times = buf.add((np.arange(n) / clip.fps).astype(np.float32), bounds=True)

    def animate(node: int, path: str, values: np.ndarray) -> None:
        samplers.append({"input": times, "output": buf.add(values.astype(np.float32)), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})

    offsets = clip.offsets().astype(float)
    rot = sixd_to_matrix(clip.rot6d.astype(float))                           # (N, H, 22, 3, 3)
    quat = np.roll(matrix_to_quat(rot), -1, axis=-1)                         # wxyz -> glTF xyzw
    roots = []
    for h in range(num_humans):
        first_joint = len(nodes) + 1
        nodes.append({"name": names[h], "children": [first_joint]})
        roots.append(len(nodes) - 1)
        for j in range(NUM_JOINTS):
            q = _continuous(quat[:, h, j])
            translation = clip.joints[0, h, 0] if PARENTS[j] < 0 else offsets[h, j]
            nodes.append({"name": JOINT_NAMES[j], "translation": np.asarray(translation, float).tolist(),
                          "rotation": q[0].tolist()})
            if CHILDREN[j]:
                nodes[-1]["children"] = [first_joint + c for c in CHILDREN[j]]
            animate(first_joint + j, "rotation", q)
            if PARENTS[j] < 0:
                animate(first_joint + j, "translation", clip.joints[:, h, 0])
        body, bones, rest = _body_mesh(offsets[h])
        bind = np.tile(np.eye(4, dtype=np.float32), (NUM_JOINTS, 1, 1))
        bind[:, 3, :3] = -rest                         # inverse bind: the rest joint to the origin (column-major)
        skins.append({"name": names[h], "joints": list(range(first_joint, first_joint + NUM_JOINTS)),
                      "skeleton": first_joint, "inverseBindMatrices": buf.add(bind.reshape(NUM_JOINTS, 16))})
        nodes.append({"name": f"{names[h]}_body", "mesh": _add_mesh(buf, meshes, body, h, bones), "skin": h})
        roots.append(len(nodes) - 1)
    for o, (spec, oid) in enumerate(zip(object_specs(clip), _object_ids(object_specs(clip)))):
        pose = clip.obj_pose[:, o].astype(float)
        q = _continuous(np.roll(pose[:, 3:] / np.linalg.norm(pose[:, 3:], axis=-1, keepdims=True), -1, axis=-1))
        nodes.append({"name": oid, "translation": pose[0, :3].tolist(), "rotation": q[0].tolist(),
                      "mesh": _add_mesh(buf, meshes, spec.mesh(), len(materials) - 1)})
        roots.append(len(nodes) - 1)
        animate(len(nodes) - 1, "translation", pose[:, :3])
        animate(len(nodes) - 1, "rotation", q)
    name = clip.scenario or "motion"
    document = {
        "asset": {"version": "2.0", "generator": "sketch2colab export_gltf",
                  "extras": {"fps": float(clip.fps), "frames": n, "scenario": clip.scenario}},
        "scene": 0, "scenes": [{"name": name, "nodes": roots,
                                "extras": {"frame_start": 0, "frame_end": n - 1, "fps": float(clip.fps)}}],
        "nodes": nodes, "meshes": meshes, "materials": materials, "skins": skins,
        "animations": [{"name": name, "samplers": samplers, "channels": channels}],
        "buffers": [{"byteLength": len(buf.data)}],
        "bufferViews": buf.views, "accessors": buf.accessors,
    }
    return document, bytes(buf.data)


def glb_bytes(document: dict, binary: bytes) -> bytes:
    """GLB container: 12-byte header, JSON chunk (space padded), BIN chunk (zero padded)."""
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (struct.pack("<III", _GLB_MAGIC, 2, total) + struct.pack("<II", len(text), _JSON_CHUNK) + text
            + struct.pack("<II", len(binary), _BIN_CHUNK) + binary)


def export_gltf(clip: MotionClip, path: str | Path) -> Path:
    """Write the animated scene as a binary glTF (.glb)."""
    path = Path(path)
    write_bytes(path, glb_bytes(*gltf_document(clip)))
    return path


# ---- command-line hook --------------------------------------------------------------------------

def add_export_arguments(parser: argparse.ArgumentParser) -> None:
    """Options a command that produces a clip can offer: --npz, --bvh-dir, --object-csv, --glb."""
    parser.add_argument("--npz", type=Path, help="write the motion clip NPZ here")
    parser.add_argument("--bvh-dir", type=Path, help="write one BVH per person into this folder")
    parser.add_argument("--object-csv", type=Path, help="write the object path (CSV) here")
    parser.add_argument("--glb", type=Path, help="write an animated glTF binary (.glb) here")


def check_export_paths(args: argparse.Namespace) -> None:
    """Refuse, before any work, export paths no file can be written to (OutputPathError)."""
    for name in ("npz", "object_csv", "glb"):
        if getattr(args, name, None):
            check_output_path(getattr(args, name))
    if getattr(args, "bvh_dir", None) and Path(args.bvh_dir).exists() and not Path(args.bvh_dir).is_dir():
        raise OutputPathError(f"{args.bvh_dir}: is not a folder (--bvh-dir takes a folder)")


def export_requested(clip: MotionClip, args: argparse.Namespace) -> list[Path]:
    """Run every export named by `add_export_arguments` options; returns the written files.
    --object-csv on a clip without an object raises ValueError."""
    written = []
    if getattr(args, "npz", None):
        written.append(export_npz(clip, args.npz))
    if getattr(args, "bvh_dir", None):
        written += export_bvh_dir(clip, args.bvh_dir)
    if getattr(args, "object_csv", None):
        written.append(export_object_path(clip, args.object_csv))
    if getattr(args, "glb", None):
        written.append(export_gltf(clip, args.glb))
    return written
