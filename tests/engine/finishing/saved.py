"""Raw generations of the shipped model saved beside the finishing tests: NAME.json the storyboard,
NAME.npz its joints, object pose and anchors (and the phase planner's occupancy where saved)."""
from pathlib import Path

import numpy as np

from engine.clip import MotionClip
from engine.storyboard import Storyboard

HERE = Path(__file__).parent


def saved_generation(name: str) -> tuple[Storyboard, MotionClip]:
    sb = Storyboard.from_json((HERE / f"{name}.json").read_text())
    saved = np.load(HERE / f"{name}.npz")
    phase = {"phase": saved["phase"]} if "phase" in saved.files else {}
    clip = MotionClip.from_joints(saved["joints"], sb.fps, obj_pose=saved["obj_pose"], obj_anchors=saved["obj_anchors"],
                                  obj_type=np.array([o.spec.type for o in sb.objects]),
                                  obj_size=np.array([o.spec.size for o in sb.objects], np.float32), **phase)
    return sb, clip
