import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinmo.ancsh.postprocess import estimate
from kinmo.ancsh.structure import KinematicStructure
from kinmo.ancsh.targets import joint_targets
from kinmo.metrics.pose import rotation_error_deg


def _box_points(rng, lo, hi, n):
    return rng.uniform(lo, hi, size=(n, 3))


def _scene(joint_type: str, state: float, seed: int = 0):
    """A cabinet-like object at rest in NAOCS: base slab + door (revolute about a vertical
    edge) or drawer (prismatic along z); then articulated and seen by a similarity camera."""
    rng = np.random.default_rng(seed)
    base = _box_points(rng, [0.0, 0.0, 0.0], [0.8, 0.9, 0.5], 600)
    mov = _box_points(rng, [0.0, 0.0, 0.5], [0.8, 0.9, 0.55], 400)
    naocs = np.vstack([base, mov])
    seg = np.r_[np.zeros(len(base), int), np.ones(len(mov), int)]
    if joint_type == "revolute":
        origin, direction = np.array([0.0, 0.0, 0.55]), np.array([0.0, 1.0, 0.0])
    else:
        origin, direction = np.array([0.4, 0.45, 0.5]), np.array([0.0, 0.0, 1.0])
    structure = KinematicStructure((-1, 0), (joint_type,))
    # NPCS of each part: its rest-state tight box normalised to unit diagonal, centred at 0.5
    npcs = np.zeros_like(naocs)
    for k in range(2):
        p = naocs[seg == k]
        lo, hi = p.min(0), p.max(0)
        npcs[seg == k] = (p - (lo + hi) / 2) / np.linalg.norm(hi - lo) + 0.5
    # articulate
    art = naocs.copy()
    m = seg == 1
    if joint_type == "revolute":
        r = Rotation.from_rotvec(direction * state).as_matrix()
        art[m] = (art[m] - origin) @ r.T + origin
    else:
        art[m] = art[m] + direction * state
    cam_r = Rotation.from_rotvec([0.3, -0.8, 0.2]).as_matrix()
    cam_s, cam_t = 1.7, np.array([0.1, -0.2, 2.5])
    pts = cam_s * art @ cam_r.T + cam_t
    tg = joint_targets(naocs, seg, structure, origin[None], direction[None], theta=0.2)
    pred = {
        "seg_logits": np.eye(2)[seg] * 10.0,
        "npcs": np.repeat(npcs[:, None], 2, axis=1),
        "naocs": naocs,
        "heatmap": tg["heatmap"],
        "unitvec": tg["unitvec"],
        "axis": tg["axis"],
        "joint_logits": np.eye(2)[tg["joint"]] * 10.0,
    }
    truth = dict(cam_r=cam_r, cam_s=cam_s, cam_t=cam_t, origin=origin, direction=direction, state=state)
    return pts, pred, structure, truth


@pytest.mark.parametrize("refine", [False, True])
def test_revolute_pose_axis_and_state_are_recovered_from_perfect_predictions(refine):
    pts, pred, st, t = _scene("revolute", 0.6)
    est = estimate(pts, pred, st, refine=refine)
    assert rotation_error_deg(est.parts[0].rotation, t["cam_r"]) < 0.5
    door_r = Rotation.from_rotvec(t["direction"] * 0.6).as_matrix()
    assert rotation_error_deg(est.parts[1].rotation, t["cam_r"] @ door_r) < 0.5
    j = est.joints[0]
    d_true = t["cam_r"] @ t["direction"]
    assert abs(abs(j.direction @ d_true) - 1) < 1e-4
    sign = np.sign(j.direction @ d_true)
    assert sign * j.state == pytest.approx(0.6, abs=0.01)
    # the axis passes through the true hinge line
    o_true = t["cam_s"] * t["cam_r"] @ t["origin"] + t["cam_t"]
    off = (j.origin - o_true) - ((j.origin - o_true) @ d_true) * d_true
    assert np.linalg.norm(off) < 0.02


def test_prismatic_state_is_recovered_in_camera_units():
    pts, pred, st, t = _scene("prismatic", 0.3)
    est = estimate(pts, pred, st)
    j = est.joints[0]
    d_true = t["cam_r"] @ t["direction"]
    sign = np.sign(j.direction @ d_true)
    # 0.3 NAOCS units seen at scale 1.7
    assert sign * j.state == pytest.approx(0.3 * 1.7, rel=0.02)
    assert rotation_error_deg(est.parts[1].rotation, est.parts[0].rotation) < 1.0


def test_structure_mismatch_is_a_clear_error():
    pts, pred, _, _ = _scene("revolute", 0.2)
    with pytest.raises(ValueError, match="do not match the structure"):
        estimate(pts, pred, KinematicStructure((-1, 0, 0), ("revolute", "revolute")))


def test_structure_validation():
    with pytest.raises(ValueError):
        KinematicStructure((0, 0), ("revolute",))
    with pytest.raises(ValueError):
        KinematicStructure((-1, 0), ("screw",))
    assert KinematicStructure((-1, 0, 0), ("revolute", "prismatic")).signature() == "0<R-1,0<P-2"


@pytest.mark.parametrize("joint_type,state", [("revolute", 0.6), ("prismatic", 0.3)])
def test_a_misoriented_naocs_does_not_tilt_axis_or_parts_when_npcs_is_right(joint_type, state):
    """The joint constraint maps the voted rest-frame (NAOCS) axis by the parent part's rotation
    (ANCSH Sec. 4.3: ``R_child = R_parent R(d, theta)``), so the axis direction and the part
    poses follow from the NPCS alone. Tying the parts with the axis carried by the separate
    NAOCS -> camera fit instead puts the NAOCS fit's error into both (the defect: ~6 deg of axis
    error on generated laptops while the per-point axis was within 0.7 deg)."""
    pts, pred, st, t = _scene(joint_type, state)
    tilt = Rotation.from_rotvec(np.radians(12.0) * np.array([1.0, 0.0, 0.0])).as_matrix()
    c = np.full(3, 0.5)
    pred = dict(pred, naocs=(pred["naocs"] - c) @ tilt.T + c)  # NAOCS head 12 deg off, axis head right
    est = estimate(pts, pred, st)
    d_true = t["cam_r"] @ t["direction"]
    assert np.degrees(np.arccos(min(1.0, abs(est.joints[0].direction @ d_true)))) < 0.5
    assert rotation_error_deg(est.parts[0].rotation, t["cam_r"]) < 0.5
    child = Rotation.from_rotvec(t["direction"] * state).as_matrix() if joint_type == "revolute" else np.eye(3)
    assert rotation_error_deg(est.parts[1].rotation, t["cam_r"] @ child) < 0.5
    if joint_type == "revolute":
        sign = np.sign(est.joints[0].direction @ d_true)
        assert sign * est.joints[0].state == pytest.approx(state, abs=0.01)


@pytest.mark.parametrize("threshold", [0.05, 0.1, 0.2])
def test_naocs_fit_uses_the_base_only_as_moving_parts_are_articulated(threshold):
    """NAOCS is the object at rest while the scan is articulated: the NAOCS -> camera similarity
    (which places the joint axis) comes from the base part's points. Fitted on every point, the
    door's points at another state than rest pulled it off as soon as the RANSAC threshold let
    some of them in (joint origin 0.037 off at 10%)."""
    pts, pred, st, t = _scene("revolute", 1.2)
    radius = np.linalg.norm(pts - pts.mean(0), axis=1).max()
    est = estimate(pts, pred, st, inlier_threshold=threshold * radius)
    g = est.naocs_to_camera
    assert rotation_error_deg(g.rotation, t["cam_r"]) < 0.05
    assert g.scale == pytest.approx(t["cam_s"], rel=1e-4)
    np.testing.assert_allclose(g.translation, t["cam_t"], atol=1e-4)
    j = est.joints[0]
    d_true = t["cam_r"] @ t["direction"]
    o_true = t["cam_s"] * t["cam_r"] @ t["origin"] + t["cam_t"]
    off = (j.origin - o_true) - ((j.origin - o_true) @ d_true) * d_true
    assert np.linalg.norm(off) < 0.005
