"""Geometry the whole engine shares, with no knowledge of storyboards or models.

    polylines.py        nearest points and distances on polylines, arc-length resampling (numpy)
    rotations.py        quaternions, rotation matrices, 6D, Euler angles, slerp (numpy)
    rotations_torch.py  the torch twins the guidance energies and the evaluator differentiate
Signed distances of objects live with the objects (engine.objects, and the energies' torch twin).
"""
