"""Metrics of DESIGN.md section 4 on hand-made cases with known answers."""
import numpy as np
import pytest

from engine import metrics as M
from engine.body import JOINT_RADII
from engine.clip import MotionClip
from engine.geometry.polylines import point_polyline_distance
from engine.objects import ObjectSpec
from engine.skeleton import JOINT_INDEX, rest_pose
from engine.storyboard import Agent, Contact, Keypose, ObjectKey, ObjectPath, SceneObject, Storyboard, Trajectory

N = 30
WRIST = JOINT_INDEX["l_wrist"]


def people(apart: float = 3.0) -> np.ndarray:
    """(N, 2, 22, 3): two people in rest pose `apart` metres apart along x."""
    joints = np.repeat(rest_pose()[None, None], N, 0).repeat(2, 1)
    joints[:, 1, :, 0] += apart
    return joints


def storyboard(**kw) -> Storyboard:
    sb = Storyboard(length=N, agents=[Agent("a"), Agent("b")])
    for name, items in kw.items():
        getattr(sb, name).extend(items)
    return sb


def clip(joints, **kw) -> MotionClip:
    return MotionClip(fps=20.0, joints=joints, rot6d=np.zeros(joints.shape[:-1] + (6,)), **kw)


def test_polyline_distance_of_a_point_at_distance_d():
    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    for d in (0.0, 0.07, 0.5):
        assert point_polyline_distance(np.array([[1.3, d]]), line)[0] == pytest.approx(d)
    assert point_polyline_distance(np.array([[3.0, 0.0]]), line)[0] == pytest.approx(1.0)   # past the end
    assert point_polyline_distance(np.array([[0.3, 0.4]]), np.zeros((2, 2)))[0] == pytest.approx(0.5)


def test_keypose_errors_one_joint_10cm_off():
    joints = people()
    target = joints.copy()
    target[5, 0, WRIST, 2] += 0.1
    mask = np.zeros(joints.shape[:3], bool)
    mask[5, 0, [0, WRIST]] = True
    assert np.mean(M.keypose_errors_3d(joints, target, mask)) == pytest.approx(0.05)
    mask[5, 0, 0] = False
    assert np.mean(M.keypose_errors_3d(joints, target, mask)) == pytest.approx(0.1)
    cam = Storyboard().camera
    kp2d = cam.project(joints)
    kp2d[5, 0, WRIST] += (0.06, 0.08)
    assert np.mean(M.keypose_errors_2d(joints, kp2d, mask, cam)) == pytest.approx(0.1)


def test_adherence_known_values():
    joints = people()
    sb = storyboard()
    cam = sb.camera
    pts = cam.project(joints[10, 0])
    mask = np.zeros(22, bool)
    mask[WRIST] = True
    sb.keyposes.append(Keypose("a", 10, pts + (0.1, 0.0), mask))
    pelvis = cam.project(joints[0, 1, 0])
    sb.trajectories.append(Trajectory("b", "pelvis", 0, N - 1, np.array([pelvis + (-1, 0.2), pelvis + (1, 0.2)])))
    reference = clip(joints + np.array([0.0, 0.0, 0.3]))
    got = M.adherence(clip(joints), sb, reference)
    assert got["K2D"] == pytest.approx(0.1)
    assert got["T2D"] == pytest.approx(0.2)
    assert got["K3D"] == pytest.approx(0.3)
    assert got["T3D"] == pytest.approx(0.3)
    assert got["MPJPE"] == pytest.approx(0.3) and got["Pelvis"] == pytest.approx(0.3)
    assert got["fail@0.2"] == 1.0 and got["fail@0.5"] == 0.0
    assert got["Pen"] == 0.0 and got["FootSkate"] == 0.0
    assert "Anc" not in got and "Obj" not in got


def test_failure_rates():
    errors = [np.array([0.1, 0.15]), np.array([0.1, 0.3]), np.array([0.6]), np.zeros(0)]
    assert M.failure_rates(errors) == {"fail@0.2": 0.5, "fail@0.5": 0.25}


def test_penetration_of_a_point_inside_a_box():
    joints = people()
    wrist = joints[0, 0, WRIST]
    pose = np.zeros((N, 1, 7))
    pose[..., 3] = 1.0
    pose[..., :3] = (wrist[0] + 0.195, wrist[1] - 0.175, wrist[2])   # wrist 0.03 deep in the box
    box = [ObjectSpec("box")]
    mean, deep = M.penetration(joints, pose, box, radii=np.zeros(43))
    assert mean == pytest.approx(0.03) and deep == 0.0
    mean, deep = M.penetration(joints, pose, box)                        # with the wrist's sphere
    assert mean == pytest.approx(0.03 + JOINT_RADII[WRIST]) and deep == 1.0
    sunk = joints.copy()
    sunk[:10, 1, :, 1] -= 0.1                                            # 8 cm below ground
    mean, deep = M.penetration(sunk)
    assert mean == pytest.approx(0.08 * 10 / N) and deep == pytest.approx(10 / N)


def test_penetration_between_people():
    joints = people(apart=0.0)
    joints[:, 1, :, 2] += 0.5                                            # 0.5 m behind: no overlap
    assert M.penetration(joints)[0] == 0.0
    joints[:, 1, :, 2] -= 0.45                                           # torsos overlap
    assert 0.2 - 0.05 <= M.penetration(joints)[0] < 0.2                  # pelvis spheres 0.1 + 0.1 at 5 cm


def test_anchor_and_object_errors():
    joints = people()
    anchors = np.zeros((N, 1, 2, 3))
    anchors[:, 0, 1] = joints[:, 0, JOINT_INDEX["r_wrist"]] + (0.0, 0.04, 0.0)
    held = np.full((N, 2, 2), -1)
    held[5:15, 0, 1] = 1
    assert M.anchor_error(joints, anchors, held) == pytest.approx(0.04)
    assert M.anchor_error(joints, anchors, np.full((N, 2, 2), -1)) == 0.0
    pose = np.zeros((N, 1, 7))
    target = np.zeros((N, 1, 3))
    target[:, 0, 0] = 0.25
    mask = np.zeros((N, 1), bool)
    mask[::3] = True
    assert M.object_position_error(pose, target, mask) == pytest.approx(0.25)


def test_object_2d_is_the_centre_at_keys_and_the_base_on_the_path():
    """A box that rests, then slides along x: its keys' outlines drawn round its middle and its
    path through its base (as engine.sketchify traces them), or through its middle (as an artist
    draws it: engine.controls.base_path), are met exactly, however unevenly it goes along the
    path (a path has no timing, as T2D); a path 10 cm under its base is 10 cm off."""
    spec, cam = ObjectSpec("box"), Storyboard().camera
    pose = np.zeros((N, 1, 7))
    pose[..., 3] = 1.0
    pose[N // 2:, 0, 0] = np.linspace(0.0, 1.0, N - N // 2)
    base = cam.project(pose[:, 0, :3])
    centre = cam.project(pose[:, 0, :3] + (0.0, spec.size[1] / 2, 0.0))
    outline = centre[10] + np.array([[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]])

    def obj_2d(path: np.ndarray) -> float:
        sb = storyboard(object_keys=[ObjectKey("box", 10, outline)], object_paths=[ObjectPath("box", 0, N - 1, path)])
        sb.objects.append(SceneObject("box", spec))
        return M.adherence(clip(people(), obj_pose=pose), sb)["Obj2D"]

    assert obj_2d(base[[0, -1]]) == pytest.approx(0.0, abs=1e-6)
    assert obj_2d(centre[[0, -1]]) == pytest.approx(0.0, abs=1e-6)
    assert obj_2d(base[[0, -1]] - (0.0, 0.1)) == pytest.approx(0.1 * N / (N + 1), rel=0.05)


def test_contact_f1():
    seq = np.array([0, 1, 1, 1, 0, 0, 1], bool)
    assert M.contact_f1(seq, seq) == 1.0
    assert M.contact_f1(np.zeros(5, bool), np.zeros(5, bool)) == 1.0
    assert M.contact_f1(~seq, seq) == 0.0
    pred = np.array([0, 1, 1, 0, 0, 0, 0], bool)                         # precision 1, recall 1/2
    assert M.contact_f1(pred, seq) == pytest.approx(2 / 3)


def test_ece_and_brier():
    labels = np.array([1, 1, 1, 0, 0, 0, 0, 0, 0, 0])
    calibrated = np.full(10, 0.3)                                        # 30 % said, 30 % true
    assert M.expected_calibration_error(calibrated, labels) == pytest.approx(0.0)
    assert M.expected_calibration_error(labels.astype(float), labels) == 0.0
    assert M.expected_calibration_error(1.0 - labels, labels) == pytest.approx(1.0)
    # two bins: 0.25 said for 4 samples with 2 positives (gap 0.25), 0.95 for 2 with 2 (gap 0.05)
    prob = np.array([0.25, 0.25, 0.25, 0.25, 0.95, 0.95])
    lab = np.array([1, 1, 0, 0, 1, 1])
    assert M.expected_calibration_error(prob, lab) == pytest.approx(4 / 6 * 0.25 + 2 / 6 * 0.05)
    assert M.brier_score(calibrated, labels) == pytest.approx(0.3 * 0.49 + 0.7 * 0.09)
    assert M.brier_score(labels, labels) == 0.0


def test_foot_skate_windows():
    joints = people()
    joints[:, :, :, 0] += np.arange(N)[:, None, None] * 0.05             # everyone slides at 1 m/s
    assert M.foot_skate_ratio(joints, 20.0) == 1.0
    assert M.foot_skate_ratio(joints, 20.0, window=5) == 1.0
    wobble = people()
    wobble[::2, :, :, 0] += 0.03                                          # 0.6 m/s back and forth
    assert M.foot_skate_ratio(wobble, 20.0) == 1.0
    assert M.foot_skate_ratio(wobble, 20.0, window=5) == 0.0              # 0.03 m over 5 frames: jitter


def test_diversity():
    a = people()
    assert M.diversity(np.stack([a, a, a])) == 0.0
    assert M.diversity(np.stack([a, a + (0.0, 0.3, 0.4)])) == pytest.approx(0.5)
    assert M.diversity(a[None]) == 0.0


def test_frechet_distance():
    mu, sigma = np.array([1.0, 2.0]), np.array([[2.0, 0.3], [0.3, 1.0]])
    assert M.frechet_distance(mu, sigma, mu, sigma) == pytest.approx(0.0, abs=1e-9)
    # 1D: (m1 - m2)^2 + (s1 - s2)^2 for standard deviations s1, s2
    assert M.frechet_distance(np.array([0.0]), np.array([[4.0]]), np.array([3.0]), np.array([[1.0]])) == \
        pytest.approx(9.0 + 1.0)
    # diagonal covariances: per axis sums
    d = M.frechet_distance(np.zeros(2), np.diag([1.0, 9.0]), np.ones(2), np.diag([4.0, 1.0]))
    assert d == pytest.approx(2.0 + (1 - 2) ** 2 + (3 - 1) ** 2)
    # singular covariances stay finite
    assert np.isfinite(M.frechet_distance(np.zeros(3), np.zeros((3, 3)), np.ones(3), np.zeros((3, 3))))


def test_r_precision():
    rng = np.random.default_rng(0)
    motion = rng.normal(size=(64, 8))
    assert M.r_precision(motion, motion) == 1.0                          # each finds itself first
    shuffled = np.roll(motion, 1, axis=0)                                # every match is someone else
    assert M.r_precision(motion + 0.0, shuffled, top_k=1) < 0.2
    # hand-checked batch of 4: storyboard i's own motion is ranked i-th nearest
    story = np.zeros((4, 1))
    motions = np.array([[0.1], [0.25], [0.35], [0.45]])                  # rank of own: 0, 1, 2, 3
    story[:, 0] = [0.0, 0.3, 0.3, 0.3]
    motions[1:, 0] = [0.2, 0.42, 0.49]
    # story 1 at 0.3: distances .2,.1,.12,.2 -> own (.1) rank 0; story 2: own .12 -> rank 1;
    # story 3: own .19, closer .1 and .12 -> rank 2
    assert M.r_precision(story, motions, top_k=1, batch=4) == pytest.approx(2 / 4)
    assert M.r_precision(story, motions, top_k=3, batch=4) == pytest.approx(4 / 4)
    assert M.r_precision(story, motions, top_k=2, batch=4) == pytest.approx(3 / 4)


def test_adherence_with_objects_contacts_and_phase():
    joints = people()
    sb = storyboard(contacts=[Contact("a", "right", 5, 14, object="box", anchor=1)])
    sb.objects.append(SceneObject("box", ObjectSpec("box")))
    pose = np.zeros((N, 1, 7))
    pose[..., 3] = 1.0
    pose[..., 2] = 2.0
    anchors = np.zeros((N, 1, 2, 3))
    anchors[:, 0, 1] = joints[:, 0, JOINT_INDEX["r_wrist"]] + (0.05, 0.0, 0.0)
    phase = np.zeros((N, 3))
    phase[:, 0] = 1.0
    phase[5:15] = (0.0, 0.2, 0.8)
    got = M.adherence(clip(joints, obj_pose=pose, obj_anchors=anchors, phase=phase), sb)
    assert got["Anc"] == pytest.approx(0.05)
    assert got["ContactF1"] == 1.0 and got["ECE"] == pytest.approx(0.0) and got["Brier"] == 0.0
    assert got["Pen"] == 0.0
    with pytest.raises(ValueError, match="frames"):
        M.adherence(clip(joints[:10]), sb)
