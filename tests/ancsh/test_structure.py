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
