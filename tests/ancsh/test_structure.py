from collections import Counter

import pytest

from kinmo.ancsh.structure import category_structure, object_parts
from kinmo.data.readers import find_shapes, read_shape


@pytest.mark.exactdata
def test_real_objects_map_to_structures(mobility_root):
    per_cat: dict[str, dict] = {}
    for path in find_shapes(mobility_root):
        shape = read_shape(path)
        per_cat.setdefault(shape.category, {})[shape.id] = object_parts(shape.links)
    # refrigerators: every fitting object has its base as part 0 and revolute doors only
    st, fitting = category_structure(per_cat["Refrigerator"])
    assert st is not None and fitting
    assert set(st.joint_types) == {"revolute"}
    assert all(p == 0 for p in st.parents[1:])
    for oid in fitting:
        op = per_cat["Refrigerator"][oid]
        assert op.structure == st
        assert sorted(set(op.link_part.values())) == list(range(st.n_parts))
    # the chosen structure is the most common one
    counts = Counter(o.structure for o in per_cat["Refrigerator"].values() if o is not None)
    assert counts[st] == max(counts.values())


def test_cylindrical_joints_are_prismatic(mobility_root):
    """A slider that rotates (a screw cap) is a prismatic joint of the structure."""
    seen = 0
    for path in find_shapes(mobility_root):
        shape = read_shape(path)
        rotating = [lk.id for lk in shape.links if lk.joint.rotates]
        if not rotating:
            continue
        op = object_parts(shape.links)
        assert op is not None, shape.id
        for lid in rotating:
            if lid in op.joint_links:  # the head of a moving rigid group starts a part
                assert op.structure.joint_types[op.joint_links.index(lid)] == "prismatic"
                seen += 1
    assert seen > 0  # the data's README counts the sliders with `rotates`


def _temples(left_y: float, right_y: float, left_id: int, right_id: int):
    """Eyeglasses: a frame (root) and two temples ('leg') hinged on it, at x = -0.5 and +0.5."""
    import numpy as np

    from kinmo.data.model import Joint, JointType, Link

    hinge = Joint(JointType.HINGE, np.zeros(3), np.array([0.0, 1.0, 0.0]), (0.0, 80.0))
    links = [Link(9, -1, "base_body", (0,), Joint(JointType.FREE)),
             Link(left_id, 9, "leg", (1,), hinge), Link(right_id, 9, "leg", (2,), hinge)]
    centroids = {9: np.array([0.0, 0.0, 0.3]), left_id: np.array([-0.5, left_y, -0.2]),
                 right_id: np.array([0.5, right_y, -0.2])}
    return links, centroids


@pytest.mark.parametrize("left_id, right_id", [(0, 1), (1, 0)])
@pytest.mark.parametrize("dy", [-4e-8, 0.0, 4e-8, 0.02])
def test_siblings_side_by_side_are_numbered_left_to_right_whatever_noise_in_height(left_id, right_id, dy):
    """Two temples at the same height up to modelling noise (PartNet-Mobility 101291 and 101303
    differ by 4e-8 in the temples' heights, one each way): the left one is part 1 in both,
    whatever the link ids. Without the place tolerance the higher temple came first."""
    links, centroids = _temples(dy, 0.0, left_id, right_id)
    op = object_parts(links, centroids)
    assert op.link_part[left_id] == 1 and op.link_part[right_id] == 2
    assert op.joint_links == (left_id, right_id)


def test_siblings_in_rows_are_numbered_top_to_bottom_then_left_to_right():
    """Four drawers of a 2 x 2 chest, centroid heights with noise within each row: top row
    first, each row from left to right; a row apart by more than the tolerance is another row."""
    import numpy as np

    from kinmo.ancsh.structure import PLACE_TOLERANCE, sibling_places
    from kinmo.data.model import Joint, JointType, Link

    slide = Joint(JointType.SLIDER, np.zeros(3), np.array([0.0, 0.0, 1.0]), (0.0, 0.4))
    pos = {1: (0.4, 0.2 + 1e-6), 2: (-0.4, 0.2), 3: (0.4, -0.2), 4: (-0.4, -0.2 - 1e-6)}
    links = [Link(0, -1, "base", (0,), Joint(JointType.FREE))] + \
        [Link(k, 0, "drawer", (k,), slide) for k in pos]
    centroids = {0: np.zeros(3)} | {k: np.array([x, y, 0.1]) for k, (x, y) in pos.items()}
    op = object_parts(links, centroids)
    assert op.joint_links == (2, 1, 4, 3)  # top left, top right, bottom left, bottom right
    # the tolerance is a fraction of the centroids' span: rows closer than it merge
    scale = 1.0
    near = {1: np.array([0.4, 0.0, 0.0]), 2: np.array([-0.4, 0.9 * PLACE_TOLERANCE, 0.0])}
    far = {1: np.array([0.4, 0.0, 0.0]), 2: np.array([-0.4, 1.1 * PLACE_TOLERANCE, 0.0])}
    assert sibling_places(near, scale)[2] < sibling_places(near, scale)[1]  # one row: left first
    assert sibling_places(far, scale)[2] < sibling_places(far, scale)[1]  # higher row first
    assert sibling_places(far, scale)[2][0] == 0 and sibling_places(far, scale)[1][0] == 1
    assert sibling_places(near, scale)[1][0] == sibling_places(near, scale)[2][0] == 0
