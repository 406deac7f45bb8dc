import numpy as np

from kinmo.ancsh.structure import KinematicStructure
from kinmo.ancsh.targets import joint_targets


def test_revolute_targets_point_to_the_axis_and_fade_with_distance():
    rng = np.random.default_rng(0)
    p = rng.uniform(-0.5, 0.5, size=(2000, 3))
    seg = (p[:, 0] > 0).astype(int)
    st = KinematicStructure((-1, 0), ("revolute",))
    o, d = np.zeros((1, 3)), np.array([[0.0, 2.0, 0.0]])  # y axis, non-unit on purpose
    t = joint_targets(p, seg, st, o, d, theta=0.2)
    dist = np.linalg.norm(p[:, [0, 2]], axis=1)
    assoc = t["joint"] == 1
    np.testing.assert_array_equal(assoc, dist < 0.2)
    np.testing.assert_allclose(t["heatmap"][assoc], 1 - dist[assoc] / 0.2, atol=1e-6)
    assert (t["heatmap"][~assoc] == 0).all()
    feet = p[assoc] + t["unitvec"][assoc] * dist[assoc, None]
    np.testing.assert_allclose(feet[:, [0, 2]], 0, atol=1e-6)
    np.testing.assert_allclose(t["axis"][assoc], [[0, 1, 0]] * assoc.sum(), atol=1e-7)
    assert t["position_mask"].sum() == assoc.sum()


def test_prismatic_associates_the_child_part_without_position():
    rng = np.random.default_rng(1)
    p = rng.uniform(-0.5, 0.5, size=(500, 3))
    seg = (p[:, 2] > 0.2).astype(int)
    st = KinematicStructure((-1, 0), ("prismatic",))
    t = joint_targets(p, seg, st, np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))
    np.testing.assert_array_equal(t["joint"] == 1, seg == 1)
    assert not t["position_mask"].any()
    assert (t["heatmap"] == 0).all()
