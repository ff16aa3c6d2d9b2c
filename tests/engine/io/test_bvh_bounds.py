"""Bounded BVH import: frame time, take length and the output rate are range-checked before
anything is allocated, and any header a hostile file holds ends in a BvhError, never another
exception (hypothesis over the header's numbers and the channel rows)."""
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.cli import main
from engine.io.bvh import BvhError, parse_bvh

TEMPLATE = """HIERARCHY
ROOT Hips
{{
  OFFSET 0 0 0
  CHANNELS {channels} Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {{
    OFFSET 0 {offset} 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {{
      OFFSET 0 10 0
    }}
  }}
}}
MOTION
Frames: {frames}
Frame Time: {frame_time}
{rows}
"""


def bvh(frames="3", frame_time="0.0333333", channels="6", offset="10", rows=None) -> str:
    rows = rows if rows is not None else "\n".join(["0 90 0 0 0 0 0 0 0"] * 3)
    return TEMPLATE.format(frames=frames, frame_time=frame_time, channels=channels, offset=offset, rows=rows)


def test_a_valid_file_parses():
    motion = parse_bvh(bvh())
    assert motion.num_frames == 3 and motion.frame_time == pytest.approx(1 / 30, rel=1e-5)


@pytest.mark.parametrize("frame_time, why", [("1000", "to 1,"), ("0", "positive"), ("-0.1", "positive"),
                                             ("nan", "positive"), ("inf", "positive"), ("1e-9", "from 0.0001")])
def test_frame_times_out_of_range_are_refused(frame_time, why):
    with pytest.raises(BvhError, match=why):
        parse_bvh(bvh(frame_time=frame_time))


def test_a_take_longer_than_an_hour_is_refused_before_its_rows_are_read():
    with pytest.raises(BvhError, match="at most 60 min"):
        parse_bvh(bvh(frames="500000", frame_time="0.01", rows=""))


def test_the_output_rate_is_bounded(tmp_path, capsys):
    path = tmp_path / "a.bvh"
    path.write_text(bvh())
    for fps in ("1e9", "0.1", "nan"):
        assert main(["import-bvh", str(path), "-o", str(tmp_path / "a.npz"), "--fps", fps]) == 2
        assert "--fps must be between 1 and 240" in capsys.readouterr().err
    assert not (tmp_path / "a.npz").exists()


number = st.one_of(st.integers(-10 ** 30, 10 ** 30).map(str), st.floats().map(repr), st.text(max_size=6),
                   st.sampled_from(["3", "0", "-1", "1e400", "0x10", "3.0", ""]))


@settings(max_examples=200, deadline=None)
@given(frames=number, frame_time=number, channels=number, offset=number,
       rows=st.lists(st.text(alphabet="0123456789 .-eE\tnaif", max_size=30), max_size=4).map("\n".join))
def test_any_header_parses_or_fails_in_one_line(frames, frame_time, channels, offset, rows):
    try:
        motion = parse_bvh(bvh(frames, frame_time, channels, offset, rows))
    except BvhError as e:
        assert "\n" not in str(e)
        return
    assert motion.num_frames >= 0
