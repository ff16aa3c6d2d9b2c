"""Real motion in and out: BVH reading and writing, retargeting to the 22-joint body, and loaders
for the InterHuman and CORE4D file layouts. Every importer returns MotionClips in our world
(metres, Y up, ground y = 0, +Z forward, +X left)."""
from .bvh import BvhError, BvhMotion, BvhNode, format_bvh, parse_bvh, read_bvh
from .bvh_export import EXPORT_ORDER, clip_to_bvh, write_bvh
from .importer import ImportConfig, ImportReport, import_bvh, people_to_clip
from .retarget import BUILTIN_MAPS, CMU_SALSA_MAP, SMPL22_MAP, JointMap, RetargetError, load_joint_map

__all__ = [
    "BvhError", "BvhMotion", "BvhNode", "format_bvh", "parse_bvh", "read_bvh",
    "EXPORT_ORDER", "clip_to_bvh", "write_bvh",
    "ImportConfig", "ImportReport", "import_bvh", "people_to_clip",
    "BUILTIN_MAPS", "CMU_SALSA_MAP", "SMPL22_MAP", "JointMap", "RetargetError", "load_joint_map",
]
