"""Contact adjacency (:mod:`kinmo.geometry.contact`): exact distances, bad inputs, FCL parity.

The reference is FCL (``python-fcl``): ``fcl.distance`` between ``BVHModel`` meshes for
every pair of leaves of real PartNet-Mobility objects, with kinmo's default relative
tolerance ``0.01 × diagonal``.
"""

from __future__ import annotations

import json
from pathlib import Path

import fcl
import numpy as np
import pytest

from kinmo import _core
from kinmo.geometry import contact_pairs, mesh_distance

#: kinmo's default contact tolerance, as a fraction of the object's bounding-box diagonal.
REL_TOL = 0.01

#: Real objects checked against FCL: the 116-leaf keyboard, many-leaf objects, small ones,
#: objects with large coplanar contacts, and large meshes (the kitchen pot 100028: 62k
#: triangles, a lid resting on the rim).
PARITY_IDS = [
    "7619", "23807", "31601", "7236", "20555", "45463", "46108", "2490", "29921",
    "100162", "100426", "8877", "10849", "11700", "103482", "20453", "45526", "46490",
    "10495", "100234", "102209", "101599", "100028", "11846", "102044", "7292",
]


def box(lo, size) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box ``[lo, lo + size]`` as 8 vertices and 12 outward triangles."""
    lo, size = np.asarray(lo, float), np.asarray(size, float)
    corners = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], float)
    v = lo + corners * size
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    return v, f


def fcl_object(v: np.ndarray, f: np.ndarray) -> fcl.CollisionObject:
    m = fcl.BVHModel()
    m.beginModel(len(v), len(f))
    m.addSubModel(v, f.astype(np.int32))
    m.endModel()
    return fcl.CollisionObject(m, fcl.Transform())


def fcl_distance(a: fcl.CollisionObject, b: fcl.CollisionObject) -> float:
    return fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult())


def leaf_meshes(folder: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """One mesh per leaf of ``result.json`` (the leaf's OBJ files merged), in pre-order."""
    leaves: list[list[str]] = []

    def walk(node: dict) -> None:
        if node.get("children"):
            for c in node["children"]:
                walk(c)
        elif node.get("objs"):
            leaves.append(node["objs"])

    for root in json.loads((folder / "result.json").read_text()):
        walk(root)
    names = sorted({n for objs in leaves for n in objs})
    loaded = dict(zip(names, _core.load_objs([str(folder / "textured_objs" / f"{n}.obj")
                                              for n in names])))
    meshes = []
    for objs in leaves:
        parts = [loaded[n] for n in objs]
        offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
        meshes.append((np.concatenate([v for v, _ in parts]),
                       np.concatenate([f + o for (_, f), o in zip(parts, offsets)])))
    return meshes


# ------------------------------------------------------------------------------ synthetic


@pytest.mark.parametrize("gap", [0.0, 0.125, 0.2421875, 0.25, 0.2578125, 0.5, 4.0])
def test_box_pair_present_iff_gap_within_tolerance(gap: float) -> None:
    tol = 0.25  # dyadic values: 1 + gap is exact, gap == tol is on the boundary
    a = box([0, 0, 0], [1, 1, 1])
    b = box([1 + gap, 0.3, -0.2], [1, 1, 1])
    pairs, dist = contact_pairs([a, b], tol)
    assert pairs.dtype == np.int64 and dist.dtype == np.float64
    assert pairs.shape == ((1, 2) if gap <= tol else (0, 2))
    assert dist.shape == (len(pairs),)
    if gap <= tol:
        assert pairs.tolist() == [[0, 1]]
        assert dist[0] == pytest.approx(gap, abs=1e-12)
    assert mesh_distance(a, b) == pytest.approx(gap, abs=1e-12)


def test_touching_and_intersecting_distance_zero() -> None:
    a = box([0, 0, 0], [1, 1, 1])
    touching = box([1, 0.5, 0.5], [1, 1, 1])
    crossing = box([0.5, 0.5, 0.5], [1, 1, 1])
    corner = box([1, 1, 1], [1, 1, 1])
    for m in (touching, crossing, corner):
        assert mesh_distance(a, m) == 0.0
    pairs, dist = contact_pairs([a, touching, crossing, corner], 0.0)
    assert pairs.tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    assert np.all(dist == 0.0)


def test_nested_surface_distance_and_far_pairs_absent() -> None:
    outer = box([0, 0, 0], [1, 1, 1])
    inner = box([0.3, 0.4, 0.2], [0.2, 0.2, 0.2])
    far = box([5, 5, 5], [1, 1, 1])
    # Surfaces, not volumes: a nested box is 0.2 away from the outer surface.
    assert mesh_distance(outer, inner) == pytest.approx(0.2, abs=1e-12)
    pairs, dist = contact_pairs([outer, far, inner], 0.3)
    assert pairs.tolist() == [[0, 2]]
    assert dist == pytest.approx([0.2], abs=1e-12)
    assert mesh_distance(outer, far) == pytest.approx(4 * np.sqrt(3), abs=1e-12)


def test_pairs_sorted_and_match_brute_force_mesh_distance() -> None:
    rng = np.random.default_rng(0)
    meshes = [box(rng.uniform(0, 3, 3), rng.uniform(0.1, 0.8, 3)) for _ in range(40)]
    tol = 0.15
    pairs, dist = contact_pairs(meshes, tol)
    want = {}
    for i in range(len(meshes)):
        for j in range(i + 1, len(meshes)):
            d = mesh_distance(meshes[i], meshes[j])
            if d <= tol:
                want[(i, j)] = d
    assert len(want) >= 10
    assert [tuple(p) for p in pairs.tolist()] == sorted(want)
    np.testing.assert_allclose(dist, [want[k] for k in sorted(want)], atol=1e-12)


def test_mesh_distance_matches_fcl_on_random_soups() -> None:
    rng = np.random.default_rng(1)
    for trial in range(10):
        soups = []
        for off in (0.0, 0.5 + 0.1 * trial):
            centres = rng.uniform(0, 1, (60, 1, 3)) + [off, 0, 0]
            v = (centres + rng.uniform(-0.15, 0.15, (60, 3, 3))).reshape(-1, 3)
            soups.append((v, np.arange(len(v)).reshape(-1, 3)))
        (va, fa), (vb, fb) = soups
        want = max(fcl_distance(fcl_object(va, fa), fcl_object(vb, fb)), 0.0)
        assert mesh_distance((va, fa), (vb, fb)) == pytest.approx(want, abs=1e-9)


def test_degenerate_meshes() -> None:
    cube = box([0, 0, 0], [1, 1, 1])
    p = [0.5, 0.5, 0.5]
    # Zero-area triangles and duplicate vertices only: a point and a segment inside the cube
    # crossing its surface.
    deg = (np.array([p, p, p, [1.5, 0.5, 0.5]]), np.array([[0, 1, 2], [0, 0, 3], [3, 3, 3]]))
    assert mesh_distance(cube, deg) == 0.0
    point = (np.array([p]), np.array([[0, 0, 0]]))
    assert mesh_distance(cube, point) == pytest.approx(0.5)
    # A mesh without faces touches nothing.
    empty = (np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    pairs, dist = contact_pairs([empty, cube, point], 1.0)
    assert pairs.tolist() == [[1, 2]]
    with pytest.raises(ValueError, match="no faces"):
        mesh_distance(empty, cube)


def test_input_conversions() -> None:
    a = box([0, 0, 0], [1, 1, 1])
    b = box([1.1, 0, 0], [1, 1, 1])
    # int32 faces, Fortran-ordered vertices, lists: converted by the wrapper.
    b32 = (np.asfortranarray(b[0]), b[1].astype(np.int32))
    pairs, dist = contact_pairs([a, b32], 0.2)
    assert pairs.tolist() == [[0, 1]] and dist[0] == pytest.approx(0.1)
    assert mesh_distance((a[0].tolist(), a[1].tolist()), b32) == pytest.approx(0.1)
    pairs, dist = contact_pairs([], 0.1)
    assert pairs.shape == (0, 2) and dist.shape == (0,)
    # Strided views reach the binding directly.
    big = np.zeros((8, 6))
    big[:, ::2] = a[0]
    pairs, _ = _core.contact_pairs([(big[:, ::2], a[1]), b], 0.2)
    assert pairs.tolist() == [[0, 1]]


@pytest.mark.parametrize(
    ("meshes", "tol", "match"),
    [
        ([(np.zeros((3, 2)), np.array([[0, 1, 2]]))], 0.1, r"meshes\[0\] vertices"),
        ([box([0, 0, 0], [1, 1, 1]), (np.zeros((3, 3)), np.array([[0, 1]]))], 0.1,
         r"meshes\[1\] faces"),
        ([(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 0, 0]]), np.array([[0, 1, 2]]))], 0.1,
         r"meshes\[0\] vertices: non-finite value at index 6"),
        ([(np.array([[0, 0, 0], [1, 0, 0], [np.inf, 0, 0]]), np.array([[0, 1, 2]]))], 0.1,
         "non-finite"),
        ([(np.eye(3), np.array([[0, 1, 3]]))], 0.1, r"meshes\[0\] faces: face 0 references vertex 3"),
        ([(np.eye(3), np.array([[0, -1, 2]]))], 0.1, "vertex -1"),
        ([box([0, 0, 0], [1, 1, 1])], -0.5, "tolerance"),
        ([box([0, 0, 0], [1, 1, 1])], float("nan"), "tolerance"),
        ([box([0, 0, 0], [1, 1, 1])], float("inf"), "tolerance"),
    ],
)
def test_contact_pairs_bad_inputs(meshes, tol, match) -> None:
    with pytest.raises(ValueError, match=match):
        contact_pairs(meshes, tol)


def test_binding_rejects_non_pairs() -> None:
    with pytest.raises(ValueError, match="meshes"):
        _core.contact_pairs(3, 0.1)
    with pytest.raises(ValueError, match=r"meshes\[0\]"):
        _core.contact_pairs([np.zeros((3, 3))], 0.1)
    with pytest.raises(ValueError, match=r"meshes\[0\]"):
        # int32 faces are converted by the Python wrapper only.
        _core.contact_pairs([(np.eye(3), np.array([[0, 1, 2]], np.int32))], 0.1)


def test_mesh_distance_bad_inputs() -> None:
    a = box([0, 0, 0], [1, 1, 1])
    with pytest.raises(ValueError, match="mesh_a vertices"):
        mesh_distance((np.full((8, 3), np.nan), a[1]), a)
    with pytest.raises(ValueError, match="mesh_b faces"):
        mesh_distance(a, (a[0], a[1] + 8))
    with pytest.raises(ValueError, match="mesh_b vertices: expected shape"):
        mesh_distance(a, (a[0][:, :2], a[1]))


# ------------------------------------------------------------------------------ real data


@pytest.mark.exactdata
@pytest.mark.parametrize("object_id", PARITY_IDS)
def test_contact_pairs_match_fcl_on_real_objects(mobility_root: Path, object_id: str) -> None:
    meshes = leaf_meshes(mobility_root / object_id)
    allv = np.concatenate([v for v, _ in meshes])
    diag = float(np.linalg.norm(allv.max(0) - allv.min(0)))
    tol = REL_TOL * diag
    pairs, dist = contact_pairs(meshes, tol)
    got = {(int(i), int(j)): float(d) for (i, j), d in zip(pairs, dist)}

    # Brute force over all pairs with FCL.
    objs = [fcl_object(v, f) for v, f in meshes]
    want = {(i, j): max(fcl_distance(objs[i], objs[j]), 0.0)
            for i in range(len(objs)) for j in range(i + 1, len(objs))}
    near = {k for k, d in want.items() if d <= tol}
    eps = 1e-6 * diag
    disagree = {k for k in set(got) ^ near if abs(want[k] - tol) > eps}
    assert not disagree, [(k, got.get(k), want[k]) for k in sorted(disagree)]
    assert len(got) >= 1
    for k, d in got.items():
        assert abs(d - want[k]) <= eps, (k, d, want[k])
    assert list(got) == sorted(got)
