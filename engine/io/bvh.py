"""The BVH motion capture format: a small reader with vectorized forward kinematics, and a writer.

Reading follows the common BVH convention: a node's local transform is a translation (its OFFSET,
with any position channels replacing the matching components) followed by its rotation channels
composed in the order they are listed (intrinsic; "Zrotation Xrotation Yrotation" means
R = Rz @ Rx @ Ry), angles in degrees. A node's global rotation is its parent's times its local one;
its global position is the parent's position plus the parent's global rotation applied to its
local translation. End Site nodes have no channels and are named "<parent name>/End Site".
Units and axes are whatever the file uses: the retargeting step maps them to ours.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry.rotations import euler_to_matrix, matrix_to_quat, quat_to_matrix
from .resample import resample_linear, resample_quaternions

END_SITE = "End Site"
_CHANNEL = re.compile(r"^([XYZ])(position|rotation)$", re.IGNORECASE)
_FRAMES = re.compile(r"^Frames\s*:\s*(\S+)$", re.IGNORECASE)
_FRAME_TIME = re.compile(r"^Frame\s+Time\s*:\s*(\S+)$", re.IGNORECASE)


MAX_FRAME_TIME_S = 1.0      # 1 frame a second; capture runs at 24-480 fps
MIN_FRAME_TIME_S = 1e-4     # 10 kHz
MAX_FILE_BYTES = 512_000_000  # an hour of one person at 120 fps is about 300 MB of text
MAX_TAKE_S = 3600.0         # an hour of motion: bounds the memory an import can ask for


class BvhError(ValueError):
    """A malformed BVH file; the message is one line and names the line at fault."""


@dataclass
class BvhNode:
    name: str
    parent: int                   # index into BvhMotion.nodes, -1 for a root
    offset: np.ndarray            # (3,) translation from the parent in the parent's frame
    channels: tuple[str, ...]     # canonical names like "Xposition", "Zrotation"; () for End Sites
    first_channel: int            # column of channels[0] in the motion data

    @property
    def is_end_site(self) -> bool:
        return self.name.endswith("/" + END_SITE)


@dataclass
class BvhMotion:
    nodes: list[BvhNode]          # parents always come before their children
    frame_time: float             # seconds per frame
    data: np.ndarray              # (F, C) channel values, columns in file order

    @property
    def fps(self) -> float:
        """1 / frame_time, snapped to a whole number when the file rounds it (0.008333 s: 120)."""
        fps = 1.0 / self.frame_time
        return float(round(fps)) if abs(fps - round(fps)) < 1e-3 * fps else fps

    @property
    def num_frames(self) -> int:
        return self.data.shape[0]

    @property
    def names(self) -> list[str]:
        return [n.name for n in self.nodes]

    def index(self, name: str) -> int:
        for i, n in enumerate(self.nodes):
            if n.name == name:
                return i
        raise KeyError(name)

    def local_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-node local translations (F, J, 3) and rotations (F, J, 3, 3)."""
        f = self.num_frames
        trans = np.empty((f, len(self.nodes), 3))
        rots = np.empty((f, len(self.nodes), 3, 3))
        for j, node in enumerate(self.nodes):
            trans[:, j] = node.offset
            order, cols = "", []
            for k, ch in enumerate(node.channels):
                col = self.data[:, node.first_channel + k]
                axis = "XYZ".index(ch[0])
                if ch.endswith("position"):
                    trans[:, j, axis] = col
                else:
                    order += ch[0]
                    cols.append(col)
            rots[:, j] = euler_to_matrix(np.stack(cols, -1), order) if order else np.eye(3)
        return trans, rots

    def global_positions(self, fps: float | None = None) -> np.ndarray:
        """(F, J, 3) world positions of every node, End Sites included.

        With `fps`, the motion is first resampled to that rate (M frames) in the joint-angle
        domain, local translations linearly and local rotations by slerp, so bones stay rigid.
        """
        trans, rots = self.local_transforms()
        if fps is not None:
            trans = resample_linear(trans, self.fps, fps)
            rots = quat_to_matrix(resample_quaternions(matrix_to_quat(rots), self.fps, fps))
        return forward_kinematics([n.parent for n in self.nodes], trans, rots)


def forward_kinematics(parents: list[int], trans: np.ndarray, rots: np.ndarray) -> np.ndarray:
    """Global positions (F, J, 3) from local translations (F, J, 3) and rotations (F, J, 3, 3).

    Parents come before children; a root's local transform is its global one.
    """
    pos = np.empty_like(trans)
    glob = np.empty_like(rots)
    for j, p in enumerate(parents):
        if p < 0:
            pos[:, j], glob[:, j] = trans[:, j], rots[:, j]
        else:
            pos[:, j] = pos[:, p] + np.einsum("fij,fj->fi", glob[:, p], trans[:, j])
            glob[:, j] = glob[:, p] @ rots[:, j]
    return pos


# ----------------------------------------------------------------------------------------- reading

class _Tokens:
    """Whitespace-separated tokens of the HIERARCHY section, each with its 1-based line number."""

    def __init__(self, lines: list[str], start: int):
        self.items: list[tuple[str, int]] = []
        self.motion_line = None
        for i in range(start, len(lines)):
            words = lines[i].split()
            if words and words[0].upper() == "MOTION":
                self.motion_line = i
                break
            # Braces may be glued to names ("head{"): split them off.
            for w in " ".join(words).replace("{", " { ").replace("}", " } ").split():
                self.items.append((w, i + 1))
        self.pos = 0

    def peek(self) -> tuple[str, int]:
        if self.pos >= len(self.items):
            line = self.items[-1][1] if self.items else 1
            raise BvhError(f"line {line}: unexpected end of the hierarchy")
        return self.items[self.pos]

    def next(self) -> tuple[str, int]:
        tok = self.peek()
        self.pos += 1
        return tok

    def expect(self, word: str) -> int:
        tok, line = self.next()
        if tok.upper() != word.upper():
            raise BvhError(f"line {line}: expected '{word}', found '{tok}'")
        return line

    def number(self) -> float:
        tok, line = self.next()
        try:
            return float(tok)
        except ValueError:
            raise BvhError(f"line {line}: expected a number, found '{tok}'") from None

    def rest_of_line(self, line: int) -> str:
        words = []
        while self.pos < len(self.items) and self.items[self.pos][1] == line and self.items[self.pos][0] != "{":
            words.append(self.items[self.pos][0])
            self.pos += 1
        return " ".join(words)


def _joint_header(tok: _Tokens, nodes: list[BvhNode], parent: int, line: int, n_channels: int) -> int:
    """Parse a ROOT/JOINT's name, '{', OFFSET and CHANNELS (after its keyword); append the node.

    Returns the running channel count.
    """
    name = tok.rest_of_line(line)
    if not name:  # name on the line after the keyword
        name, nline = tok.next()
        if name == "{":
            raise BvhError(f"line {nline}: joint without a name")
    tok.expect("{")
    tok.expect("OFFSET")
    offset = np.array([tok.number() for _ in range(3)])
    channels: list[str] = []
    word, cline = tok.peek()
    if word.upper() == "CHANNELS":
        tok.next()
        count_tok, _ = tok.next()
        if not (count_tok.isascii() and count_tok.isdigit()):
            raise BvhError(f"line {cline}: CHANNELS needs a count, found '{count_tok}'")
        for _ in range(int(count_tok)):
            ch, chl = tok.next()
            m = _CHANNEL.match(ch)
            if not m:
                raise BvhError(f"line {chl}: unknown channel '{ch}'")
            channels.append(m.group(1).upper() + m.group(2).lower())
        if len(set(channels)) != len(channels):
            raise BvhError(f"line {cline}: repeated channel in '{' '.join(channels)}'")
    nodes.append(BvhNode(name, parent, offset, tuple(channels), n_channels))
    return n_channels + len(channels)


def _end_site(tok: _Tokens, nodes: list[BvhNode], parent: int, n_channels: int) -> None:
    """Parse 'Site { OFFSET x y z }' (after 'End') and append it as '<parent>/End Site'."""
    tok.expect("Site")
    tok.expect("{")
    tok.expect("OFFSET")
    offset = np.array([tok.number() for _ in range(3)])
    tok.expect("}")
    taken = {n.name for n in nodes}
    name, k = f"{nodes[parent].name}/{END_SITE}", 2
    while name in taken:  # several End Sites under one joint (rare): keep names unique
        name, k = f"{nodes[parent].name}/{END_SITE} {k}", k + 1
    nodes.append(BvhNode(name, parent, offset, (), n_channels))


def _parse_tree(tok: _Tokens, nodes: list[BvhNode], root_line: int, n_channels: int) -> int:
    """Parse one ROOT's subtree with an explicit stack (any depth); returns the channel count."""
    n_channels = _joint_header(tok, nodes, -1, root_line, n_channels)
    open_joints = [len(nodes) - 1]
    while open_joints:
        word, line = tok.next()
        key = word.upper()
        if key == "}":
            open_joints.pop()
        elif key == "JOINT":
            n_channels = _joint_header(tok, nodes, open_joints[-1], line, n_channels)
            open_joints.append(len(nodes) - 1)
        elif key == "END":
            _end_site(tok, nodes, open_joints[-1], n_channels)
        else:
            raise BvhError(f"line {line}: expected JOINT, End Site or '}}', found '{word}'")
    return n_channels


def parse_bvh(text: str, source: str = "<bvh>") -> BvhMotion:
    """Parse BVH text. Raises BvhError naming `source` and the line on malformed input."""
    try:
        return _parse(text)
    except BvhError as e:
        raise BvhError(f"{source}: {e}") from None


def _parse(text: str) -> BvhMotion:
    lines = text.splitlines()
    first = next((i for i, l in enumerate(lines) if l.strip()), None)
    if first is None or lines[first].split()[0].upper() != "HIERARCHY":
        raise BvhError(f"line {1 if first is None else first + 1}: expected 'HIERARCHY' at the start")
    tok = _Tokens(lines, first + 1)
    nodes: list[BvhNode] = []
    n_channels = 0
    while tok.pos < len(tok.items):
        word, line = tok.next()
        if word.upper() != "ROOT":
            raise BvhError(f"line {line}: expected 'ROOT', found '{word}'")
        n_channels = _parse_tree(tok, nodes, line, n_channels)
    if not nodes:
        raise BvhError(f"line {first + 1}: the hierarchy has no ROOT")
    if tok.motion_line is None:
        raise BvhError(f"line {len(lines)}: missing 'MOTION' section")
    frames, frame_time, data_start = _motion_header(lines, tok.motion_line + 1)
    data = _motion_data(lines, data_start, frames, n_channels)
    return BvhMotion(nodes, frame_time, data)


def _header_value(lines: list[str], i: int, pattern: re.Pattern, what: str) -> tuple[str, int]:
    while i < len(lines) and not lines[i].strip():
        i += 1
    m = pattern.match(lines[i].strip()) if i < len(lines) else None
    if not m:
        raise BvhError(f"line {min(i, len(lines) - 1) + 1}: expected '{what}'")
    return m.group(1), i + 1


def _motion_header(lines: list[str], i: int) -> tuple[int, float, int]:
    value, i = _header_value(lines, i, _FRAMES, "Frames: <count>")
    if not (value.isascii() and value.isdigit()):
        raise BvhError(f"line {i}: frame count must be a whole number, found '{value}'")
    frames = int(value)
    value, i = _header_value(lines, i, _FRAME_TIME, "Frame Time: <seconds>")
    try:
        frame_time = float(value)
    except ValueError:
        frame_time = -1.0
    if not MIN_FRAME_TIME_S <= frame_time <= MAX_FRAME_TIME_S:
        raise BvhError(f"line {i}: frame time must be a positive number of seconds from "
                       f"{MIN_FRAME_TIME_S:g} to {MAX_FRAME_TIME_S:g}, found '{value}'")
    if frames * frame_time > MAX_TAKE_S:
        raise BvhError(f"line {i}: {frames} frames of {frame_time:g} s is {frames * frame_time / 60:.0f} min; "
                       f"takes are at most {MAX_TAKE_S / 60:.0f} min")
    return frames, frame_time, i


def _motion_data(lines: list[str], start: int, frames: int, n_channels: int) -> np.ndarray:
    rows = [(i + 1, lines[i].split()) for i in range(start, len(lines)) if lines[i].strip()]
    for line, row in rows:
        if len(row) != n_channels:
            raise BvhError(f"line {line}: expected {n_channels} channel values, found {len(row)}")
    if len(rows) != frames:
        line = rows[-1][0] if rows else len(lines)
        raise BvhError(f"line {line}: header says {frames} frames, found {len(rows)}")
    if frames == 0:
        return np.zeros((0, n_channels))
    try:
        data = np.array([row for _, row in rows], dtype=np.float64)
    except ValueError:
        for line, row in rows:  # find the culprit only on failure: the fast path stays one call
            try:
                np.array(row, dtype=np.float64)
            except ValueError:
                raise BvhError(f"line {line}: non-numeric channel value") from None
        raise
    if not np.all(np.isfinite(data)):
        line = rows[int(np.argmax(~np.all(np.isfinite(data), axis=1)))][0]
        raise BvhError(f"line {line}: channel value is not finite")
    return data.reshape(frames, n_channels)


def read_bvh(path: str | Path) -> BvhMotion:
    """Read a BVH file. Raises BvhError on malformed content, FileNotFoundError if missing."""
    path = Path(path)
    try:
        if path.stat().st_size > MAX_FILE_BYTES:
            raise BvhError(f"{path}: {path.stat().st_size / 1e6:.0f} MB; BVH takes are read up to "
                           f"{MAX_FILE_BYTES / 1e6:.0f} MB")
        text = path.read_text(encoding="utf-8", errors="replace")
    except IsADirectoryError:
        raise BvhError(f"{path}: is a directory, not a BVH file") from None
    return parse_bvh(text, str(path))


# ----------------------------------------------------------------------------------------- writing

def format_bvh(motion: BvhMotion, precision: int = 6) -> str:
    """BVH text for a motion; End Site nodes must be leaves named '<parent>/End Site'."""
    children: list[list[int]] = [[] for _ in motion.nodes]
    for j, node in enumerate(motion.nodes):
        if node.parent >= 0:
            children[node.parent].append(j)
    fmt = f"{{:.{precision}f}}"
    out = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        node, pad = motion.nodes[j], "\t" * depth
        offset = " ".join(fmt.format(v) for v in node.offset)
        if node.is_end_site:
            out.extend([f"{pad}End Site", f"{pad}{{", f"{pad}\tOFFSET {offset}", f"{pad}}}"])
            return
        out.append(f"{pad}{'ROOT' if node.parent < 0 else 'JOINT'} {node.name}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {offset}")
        out.append(f"{pad}\tCHANNELS {len(node.channels)} {' '.join(node.channels)}".rstrip())
        for c in children[j]:
            emit(c, depth + 1)
        out.append(f"{pad}}}")

    for j, node in enumerate(motion.nodes):
        if node.parent < 0:
            emit(j, 0)
    out += ["MOTION", f"Frames: {motion.num_frames}", f"Frame Time: {motion.frame_time:.8f}"]
    out += [" ".join(fmt.format(v) for v in row) for row in motion.data]
    return "\n".join(out) + "\n"
