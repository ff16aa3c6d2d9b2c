"""engine.finishing.finish as a whole: the full pass and a preview's (FinishConfig.polish off)."""
import numpy as np

from engine.finishing import FinishConfig, finish
from engine.finishing.misses import hold_gaps
from engine.finishing.steady import frame_pops
from engine.metrics import adherence
from engine.skeleton import forward_kinematics
from engine.geometry.rotations import sixd_to_matrix

from .saved import saved_generation


def test_a_preview_finish_keeps_keys_paths_and_grips_and_leaves_the_clean_up_out():
    storyboard, raw = saved_generation("handoff_release")
    full = finish(raw, storyboard)
    preview = finish(raw, storyboard, FinishConfig(polish=False))
    exact, quick = adherence(full, storyboard), adherence(preview, storyboard)
    assert quick["K2D"] <= 1.2 * exact["K2D"] + 0.002 and quick["T2D"] <= 1.2 * exact["T2D"] + 0.002
    assert max(gap.max() for _, _, gap in hold_gaps(preview, storyboard)) < 0.03
    # One skeleton still: the joints are its forward kinematics.
    joints = np.asarray(preview.joints, float)
    rebuilt = forward_kinematics(joints[:, :, 0], sixd_to_matrix(np.asarray(preview.rot6d, float)),
                                 np.asarray(preview.bone_offsets, float))
    assert np.abs(rebuilt - joints).max() < 1e-4
    # The smoothing of pops is what it leaves out.
    assert frame_pops(np.asarray(full.joints, float)).max() < frame_pops(joints).max()
