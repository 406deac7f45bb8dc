"""Permutation-matched errors of interchangeable parts: which parts the rule groups, and that
matching undoes a swap of interchangeable predictions and nothing else."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from rich.console import Console
from scipy.spatial.transform import Rotation

from kinmo.ancsh.evaluate import _aggregate, _StructureEval
from kinmo.ancsh.frame_metrics import FrameTruth, frame_errors, ground_truth_estimate
from kinmo.ancsh.interchangeable import (
    describe_groups,
    interchangeable_groups,
    matched_frame_errors,
    part_permutation,
    permute_estimate,
)
from kinmo.ancsh.postprocess import JointEstimate, PartPose
from kinmo.ancsh.structure import KinematicStructure
from kinmo.ancsh.symmetry import axis_rotation
from kinmo.ancsh.table2 import matched_rich_table, structures_markdown, summarize, table2_csv, table2_markdown


def _truth(types: tuple[str, ...], seed: int = 0) -> tuple[KinematicStructure, FrameTruth]:
    """A synthetic frame: base plus one child per joint type, all children of the base, each
    part in its own pose (rotations tens of degrees apart), camera frame in metres."""
    st = KinematicStructure((-1,) + (0,) * len(types), types)
    rng = np.random.default_rng(seed)
    parts = [PartPose(Rotation.from_euler("xyz", rng.uniform(-90, 90, 3), degrees=True).as_matrix(),
                      rng.normal(size=3), 0.5 + 0.1 * k, np.full(3, 0.3), 100) for k in range(st.n_parts)]
    joints = [JointEstimate(rng.normal(size=3), (d := rng.normal(size=3)) / np.linalg.norm(d),
                            float(rng.uniform(0.1, 1.0)), t) for t in types]
    return st, FrameTruth(parts, joints)


def _swapped(truth: FrameTruth, a: int, b: int):
    """The perfect estimate with parts ``a`` and ``b`` (and the joints heading them) swapped."""
    est = ground_truth_estimate(truth, np.array([0, a, b, b, a]))
    est.parts[a], est.parts[b] = est.parts[b], est.parts[a]
    est.joints[a - 1], est.joints[b - 1] = est.joints[b - 1], est.joints[a - 1]
    return est


@pytest.mark.parametrize(("parents", "types", "groups"), [
    ((-1, 0), ("revolute",), []),  # Pliers / Scissors in PartNet-Mobility: base + one half
    ((-1, 0, 0), ("revolute", "revolute"), [(1, 2)]),  # eyeglasses' temples, two doors
    ((-1, 0, 0), ("revolute", "prismatic"), []),
    ((-1, 0, 0, 0, 0), ("revolute", "prismatic", "revolute", "prismatic"), [(1, 3), (2, 4)]),
    ((-1, 0, 1, 1), ("revolute", "revolute", "revolute"), [(2, 3)]),  # part 1 has children
    ((-1, 0, 0, 1), ("revolute", "revolute", "revolute"), []),  # 1 and 2 differ below
])
def test_the_rule_groups_leaf_siblings_with_one_joint_type(parents, types, groups):
    st = KinematicStructure(parents, types)
    assert interchangeable_groups(st) == groups
    assert bool(describe_groups(groups, st)) == bool(groups)


def test_swapped_halves_have_large_raw_and_zero_matched_errors():
    st, truth = _truth(("revolute", "revolute"))
    est = _swapped(truth, 1, 2)
    raw = frame_errors(est, truth)
    assert raw.rotation_deg[1:].min() > 10 and raw.translation[1:].min() > 0.1
    matched, perm = matched_frame_errors(est, truth, interchangeable_groups(st))
    assert perm.tolist() == [0, 2, 1] and perm.dtype == np.int64
    for n in ("rotation_deg", "translation", "angle_deg", "distance", "state"):
        assert np.abs(getattr(matched, n)).max() < 1e-4, n
    np.testing.assert_allclose(matched.iou, 1.0, atol=1e-6)
    # the base's errors are the same either way
    assert matched.rotation_deg[0] == raw.rotation_deg[0]


def test_without_interchangeable_parts_matched_equals_raw():
    st, truth = _truth(("revolute", "prismatic"), seed=3)
    est = _swapped(truth, 1, 2)  # a swap across joint types: the rule does not allow undoing it
    rng = np.random.default_rng(1)
    est.parts[0] = PartPose(Rotation.random(random_state=2).as_matrix(), rng.normal(size=3), 0.5,
                            np.full(3, 0.3), 90)
    assert interchangeable_groups(st) == []
    raw = frame_errors(est, truth)
    matched, perm = matched_frame_errors(est, truth, [])
    assert perm.tolist() == [0, 1, 2]
    for n in ("rotation_deg", "translation", "iou", "state", "angle_deg", "distance"):
        np.testing.assert_array_equal(getattr(matched, n), getattr(raw, n))


def test_parts_of_different_joint_types_are_never_swapped():
    """Two revolute and two prismatic children; the estimate swaps a revolute with a
    prismatic part and the two prismatic parts: matching undoes only the prismatic swap."""
    st, truth = _truth(("revolute", "prismatic", "revolute", "prismatic"), seed=5)
    groups = interchangeable_groups(st)
    assert groups == [(1, 3), (2, 4)]
    est = ground_truth_estimate(truth)
    p = list(est.parts)
    est.parts = [p[0], p[2], p[1], p[3], p[4]]  # revolute 1 <-> prismatic 2
    perm = part_permutation(est, truth, groups)
    assert all(st.joint_types[perm[k] - 1] == st.joint_types[k - 1] for k in range(1, 5))
    est = _swapped(truth, 2, 4)
    assert part_permutation(est, truth, groups).tolist() == [0, 1, 4, 3, 2]


def test_ties_keep_the_identity():
    st, truth = _truth(("revolute", "revolute"), seed=7)
    est = ground_truth_estimate(truth)
    same = PartPose(np.eye(3), np.zeros(3), 0.5, np.full(3, 0.3), 10)
    est.parts[1], est.parts[2] = same, same
    assert part_permutation(est, truth, interchangeable_groups(st)).tolist() == [0, 1, 2]


def test_the_cost_of_a_symmetric_part_is_its_symmetry_aware_error():
    """True part 1 symmetric about its NPCS y axis, predicted turned 150 degrees about it;
    predicted part 2 is 40 degrees off true part 1 (axis tilted) and 90-odd off its own.
    Plain rotation errors favour the swap (150 + 97 > 40 + 159 degrees); with the symmetry,
    part 1 costs nothing and the identity wins (0 + 97 < 40 + 159)."""
    st, truth = _truth(("revolute", "revolute"), seed=11)
    axis = np.array([0.0, 1.0, 0.0])
    r1 = truth.parts[1].rotation
    rot = lambda ax, deg: Rotation.from_euler(ax, deg, degrees=True).as_matrix()  # noqa: E731
    truth.parts[2].rotation = r1 @ rot("x", 90)
    est = ground_truth_estimate(truth)
    est.parts[1].rotation = r1 @ axis_rotation(axis, np.radians(150))
    est.parts[2].rotation = r1 @ rot("z", 40)
    groups = interchangeable_groups(st)
    assert part_permutation(est, truth, groups).tolist() == [0, 2, 1]
    assert part_permutation(est, truth, groups, [None, axis, None]).tolist() == [0, 1, 2]
    m, _ = matched_frame_errors(est, truth, groups, [None, axis, None])
    assert m.rotation_deg[1] == pytest.approx(0.0, abs=1e-5)


def test_permute_estimate_relabels_parts_joints_and_points():
    _, truth = _truth(("revolute", "revolute"))
    est = ground_truth_estimate(truth, np.array([0, 1, 2, 2, -1]))
    out = permute_estimate(est, [0, 2, 1])
    assert out.parts[1] is est.parts[2] and out.joints[0] is est.joints[1]
    assert out.segmentation.tolist() == [0, 2, 1, 1, -1]
    for bad in ([1, 0, 2], [0, 1, 1], [0, 1]):
        with pytest.raises(ValueError, match="permutation"):
            permute_estimate(est, bad)
    with pytest.raises(ValueError, match="in 1..2"):
        part_permutation(est, truth, [(0, 1)])


def test_table_outputs_put_matched_errors_next_to_the_raw_ones():
    st, truth = _truth(("revolute", "revolute"))
    est = _swapped(truth, 1, 2)
    raw = frame_errors(est, truth)
    matched, _ = matched_frame_errors(est, truth, interchangeable_groups(st))
    row = summarize("supervised", "run", [raw, raw], st.joint_types, {}, [matched, matched], 2)
    assert row.swapped == 2 and row.matched_mean("rotation_deg") < 1e-4 < row.mean("rotation_deg")
    reader = csv.DictReader(io.StringIO(table2_csv([row], 3, 2)))
    cols = reader.fieldnames
    for n, per, width in (("rotation_deg", "part", 3), ("translation", "part", 3), ("angle_deg", "joint", 2),
                          ("distance", "joint", 2)):
        i = cols.index(f"{n}_mean")
        assert cols[i + 1 + width] == f"{n}_matched_mean"  # right after the raw columns
        assert cols[i + 2 + width:i + 2 + 2 * width] == [f"{n}_matched_{per}{k}" for k in range(width)]
    assert "iou_matched_mean" not in cols and cols[-1] == "swapped_scans"
    r = next(reader)
    assert float(r["rotation_deg_matched_mean"]) < 1e-4 < float(r["rotation_deg_mean"]) and r["swapped_scans"] == "2"
    md = table2_markdown([row], "Eyeglasses", st)
    assert "Permutation-matched errors (interchangeable parts 1, 2 (revolute children of part 0))" in md
    assert "| supervised | 2 | 2 |" in md
    # a structure without groups gets no matched table; a row without matched errors, empty cells
    st2 = KinematicStructure((-1, 0, 0), ("revolute", "prismatic"))
    assert "Permutation-matched" not in table2_markdown([row], "X", st2)
    plain = summarize("supervised", "run", [raw], st.joint_types)
    r = next(csv.DictReader(io.StringIO(table2_csv([plain], 3, 2))))
    assert r["rotation_deg_matched_mean"] == "" and r["rotation_deg_matched_part1"] == "" and r["swapped_scans"] == "0"
    # the console table fits a 140-column log without cutting a cell
    con = Console(file=io.StringIO(), width=140, force_terminal=False)
    con.print(matched_rich_table([row], "Eyeglasses", st, describe_groups(interchangeable_groups(st), st)))
    text = con.file.getvalue()
    assert "…" not in text and "matched: parts 1, 2" in text
    cells = [c.strip() for ln in text.splitlines() if "supervised" in ln for c in ln.split("│")[1:-1]]
    assert cells[:3] == ["supervised", "2", "2"] and cells[3] == f"{row.mean('rotation_deg'):.2f}"
    assert cells[4] == "0.00" and len(cells) == 11


def test_category_rows_over_structures_average_matched_errors_per_scan():
    """Two structures, one with interchangeable doors (two swapped scans) and one without:
    the category row's matched rotation error is the mean over the three scans of the
    per-scan mean over parts, and table2.md gets the category's matched table."""
    st, truth = _truth(("revolute", "revolute"))
    est = _swapped(truth, 1, 2)
    raw = frame_errors(est, truth)
    m, _ = matched_frame_errors(est, truth, interchangeable_groups(st))
    st2, truth2 = _truth(("revolute", "prismatic"), seed=2)
    est2 = _swapped(truth2, 1, 2)
    raw2 = frame_errors(est2, truth2)
    m2, _ = matched_frame_errors(est2, truth2, [])
    row = summarize("supervised", "a", [raw, raw], st.joint_types, {}, [m, m], 2)
    row2 = summarize("supervised", "b", [raw2], st2.joint_types, {}, [m2], 0)
    evals = [_StructureEval(st, [], [row], [[raw, raw]], [[m, m]], [(1, 2)], [], ["x"], 2, {}, {}, [], []),
             _StructureEval(st2, [], [row2], [[raw2]], [[m2]], [], [], ["y"], 1, {}, {}, [], [])]
    (cat,) = _aggregate(evals)
    assert cat.frames == 3 and cat.swapped == 2
    want = (2 * m.rotation_deg.mean() + raw2.rotation_deg.mean()) / 3
    assert cat.matched_mean("rotation_deg") == pytest.approx(want, rel=1e-12)
    assert cat.mean("rotation_deg") == pytest.approx((2 * raw.rotation_deg.mean() + raw2.rotation_deg.mean()) / 3)
    md = structures_markdown([cat], "X", [(st, [row], [], 1), (st2, [row2], [], 1)])
    assert md.count("| supervised | 3 | 2 |") == 1 and md.count("swapped scans") == 2  # category + doors
