"""Part graphs: structure, geometry invariants, contact against brute force, bad meshes."""

from __future__ import annotations

import itertools
from pathlib import Path

import fcl
import numpy as np
import pytest
from conftest import CABINET_BOXES

from kinmo.data.build import build_graph
from kinmo.data.graph import PartGraph
from kinmo.data.readers import read_shape
from kinmo.errors import KinmoDataError
from kinmo.geometry import load_obj

# ------------------------------------------------------------------------------- helpers


def _node_meshes(shape, node_id: int) -> list[tuple[np.ndarray, np.ndarray]]:
    return [load_obj(shape.mesh_path(n)) for n in shape.hierarchy.mesh_names(node_id)]


def _on_triangles(points: np.ndarray, v: np.ndarray, f: np.ndarray, tol: float) -> np.ndarray:
    """Distance-free test: p is on triangle abc when area(pab)+area(pbc)+area(pca) = area(abc)."""
    t = v[f]  # (F, 3, 3)
    area = np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    ok = np.zeros(len(points), dtype=bool)
    for s in range(0, len(points), 64):
        p = points[s : s + 64, None, :]  # (P, 1, 3)
        a, b, c = t[None, :, 0], t[None, :, 1], t[None, :, 2]
        tot = (
            np.linalg.norm(np.cross(a - p, b - p), axis=2)
            + np.linalg.norm(np.cross(b - p, c - p), axis=2)
            + np.linalg.norm(np.cross(c - p, a - p), axis=2)
        )
        ok[s : s + 64] = (np.abs(tot - area[None]) <= tol * (area[None] + tol)).any(axis=1)
    return ok


def _fcl_distance(ma, mb) -> float:
    def obj(m):
        bvh = fcl.BVHModel()
        bvh.beginModel(len(m[0]), len(m[1]))
        bvh.addSubModel(m[0], m[1].astype(np.int32))
        bvh.endModel()
        return fcl.CollisionObject(bvh, fcl.Transform())

    return max(0.0, fcl.distance(obj(ma), obj(mb), fcl.DistanceRequest(), fcl.DistanceResult()))


def _check_invariants(g: PartGraph, shape) -> None:
    h = shape.hierarchy
    v = g.n_nodes
    # pre-order: node ids in the hierarchy's pre-order, parents before children
    assert list(g.node_ids) == h.order
    assert g.parent[0] == -1 and (g.parent[1:] < np.arange(1, v)).all()
    for k in range(1, v):
        assert h.nodes[int(g.node_ids[k])].parent == int(g.node_ids[g.parent[k]])
        assert g.depth[k] == g.depth[g.parent[k]] + 1
    assert [bool(x) for x in g.is_leaf] == [h.nodes[int(n)].is_leaf for n in g.node_ids]
    assert np.array_equal(g.child_edges, np.stack([g.parent[1:], np.arange(1, v)], 1))
    # sibling edges: every ordered pair of distinct children, sorted, both directions
    want = sorted(
        (a, b)
        for p in range(v)
        for a, b in itertools.permutations(np.flatnonzero(g.parent == p).tolist(), 2)
    )
    assert [tuple(e) for e in g.sibling_edges.tolist()] == want
    pos = {tuple(e): k for k, e in enumerate(g.sibling_edges.tolist())}
    for (a, b), k in pos.items():
        assert g.sibling_distance[k] == g.sibling_distance[pos[(b, a)]]
        assert g.sibling_contact[k] == g.sibling_contact[pos[(b, a)]]
    cap, tol = g.meta["distance_cap"], g.meta["contact_tolerance"]
    assert (g.sibling_distance >= 0).all() and (g.sibling_distance <= cap).all()
    assert np.array_equal(g.sibling_contact, g.sibling_distance <= tol)
    assert cap == pytest.approx(0.1 * g.scale) and tol == pytest.approx(0.01 * g.scale)
    # points: float32, finite; every OBB contains its node's points
    assert g.points.dtype == np.float32 and np.isfinite(g.points).all()
    for k in range(v):
        local = (g.points[k].astype(np.float64) - g.obb_center[k]) @ g.obb_axes[k].T
        assert (np.abs(local) <= g.obb_half_extents[k] + 1e-5 * g.scale).all()
        assert np.allclose(g.obb_axes[k] @ g.obb_axes[k].T, np.eye(3), atol=1e-9)


# ------------------------------------------------------------------------ synthetic shape


def test_cabinet_graph(cabinet: Path) -> None:
    s = read_shape(cabinet)
    g = build_graph(s, n_points=256, seed=3)
    _check_invariants(g, s)
    assert g.points.shape == (8, 256, 3)
    assert list(g.parent) == [-1, 0, 0, 2, 2, 0, 0, 0]
    assert g.scale == pytest.approx(np.sqrt(1 + 1 + 0.56**2))
    assert g.shape_id == "cabinet" and g.category == "StorageFurniture"
    assert g.format == "partnet-mobility" and g.has_labels
    # every point lies on the surface of one of its node's boxes
    for k, nid in enumerate(g.node_ids):
        p = g.points[k].astype(np.float64)
        on = np.zeros(len(p), dtype=bool)
        for name in s.hierarchy.mesh_names(int(nid)):
            lo, hi = (np.asarray(x) for x in CABINET_BOXES[name])
            inside = ((p >= lo - 1e-6) & (p <= hi + 1e-6)).all(1)
            face = (np.isclose(p, lo, atol=1e-6) | np.isclose(p, hi, atol=1e-6)).any(1)
            on |= inside & face
        assert on.all(), s.hierarchy.nodes[int(nid)].name
    # both meshes of the two-mesh drawer leaf are sampled
    drawer = g.points[5].astype(np.float64)
    assert (drawer[:, 2] < 0.49).any() and (drawer[:, 2] > 0.5).any()
    # exact distances between boxes
    names = g.node_names
    d = {(names[i], names[j]): x for (i, j), x in zip(g.sibling_edges, g.sibling_distance)}
    c = {(names[i], names[j]): x for (i, j), x in zip(g.sibling_edges, g.sibling_contact)}
    cap = g.meta["distance_cap"]
    assert d[("knob", "body")] == pytest.approx(0.02, abs=1e-9) and not c[("knob", "body")]
    assert d[("door", "body")] == pytest.approx(0.0, abs=1e-9) and c[("door", "body")]
    assert d[("knob", "door")] == pytest.approx(0.0, abs=1e-9)
    assert d[("drawer", "body")] == pytest.approx(0.0, abs=1e-9)
    assert d[("panel", "handle")] == pytest.approx(0.0, abs=1e-9)
    assert d[("knob", "base")] == cap and d[("knob", "drawer")] == cap  # 0.5 and 0.22 away
    assert d[("door", "base")] == cap
    # the meta
    m = g.meta
    assert m["n_points"] == 256 and m["seed"] == 3 and m["cache_version"] >= 1
    assert m["contact_tolerance_rel"] == 0.01 and m["distance_cap_rel"] == 0.1
    assert m["counts"] == {"n_nodes": 8, "n_leaves": 6, "n_sibling_edges": 22,
                           "n_moving_joints": 3, "n_meshes": 7}
    door = next(lk for lk in m["links"] if lk["id"] == 0)
    assert door["direction"] == [0.0, 1.0, 0.0] and door["parts"] == [2]
    assert m["fine_types"][-2:] == ["Fixed", "None"]


def test_seeded_and_reproducible(cabinet: Path) -> None:
    s = read_shape(cabinet)
    a = build_graph(s, n_points=128, seed=7)
    b = build_graph(s, n_points=128, seed=7)
    c = build_graph(s, n_points=128, seed=8)
    assert np.array_equal(a.points, b.points)
    assert not np.array_equal(a.points, c.points)
    assert np.array_equal(a.obb_center, b.obb_center)
    assert np.array_equal(a.sibling_distance, c.sibling_distance)


def test_save_load_roundtrip(cabinet: Path, tmp_path: Path) -> None:
    g = build_graph(read_shape(cabinet), n_points=32)
    g.save(tmp_path / "g.npz")
    r = PartGraph.load(tmp_path / "g.npz")
    for name in ("points", "sibling_edges", "sibling_distance", "edge_fine", "node_link",
                 "obb_axes"):
        assert np.array_equal(getattr(r, name), getattr(g, name))
    assert np.array_equal(r.edge_axis_origin, g.edge_axis_origin, equal_nan=True)
    assert r.meta == g.meta and r.node_names == g.node_names and r.scale == g.scale


def test_partnet_graph_has_no_labels(tmp_path: Path, cabinet: Path) -> None:
    import shutil

    p = tmp_path / "plain"
    p.mkdir()
    shutil.copytree(cabinet / "textured_objs", p / "objs")
    shutil.copy(cabinet / "result.json", p / "result.json")
    g = build_graph(read_shape(p), n_points=16)
    assert not g.has_labels and g.node_link is None and "links" not in g.meta
    assert g.meta["counts"]["n_moving_joints"] == 0


def test_nan_vertex_names_the_obj(cabinet: Path) -> None:
    obj = cabinet / "textured_objs" / "handle.obj"
    obj.write_text(obj.read_text().replace("v 0.4 0.7 0.52", "v nan 0.7 0.52", 1))
    with pytest.raises(KinmoDataError) as info:
        build_graph(read_shape(cabinet), n_points=16)
    assert info.value.path == str(obj)
    assert "\n" not in str(info.value)


def test_zero_area_leaf_names_the_obj(cabinet: Path) -> None:
    obj = cabinet / "textured_objs" / "knob.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")  # one degenerate triangle
    with pytest.raises(KinmoDataError) as info:
        build_graph(read_shape(cabinet), n_points=16)
    assert info.value.path == str(obj) and "zero area" in info.value.problem


def test_bad_parameters(cabinet: Path) -> None:
    s = read_shape(cabinet)
    with pytest.raises(ValueError):
        build_graph(s, n_points=0)
    with pytest.raises(ValueError):
        build_graph(s, contact_tolerance=0.2, distance_cap=0.1)


# ---------------------------------------------------------------------------- real shapes


@pytest.mark.exactdata
@pytest.mark.parametrize("shape_id", ["11854", "10849", "102278"])
def test_real_graph_invariants_and_contact_brute_force(mobility_root: Path, shape_id: str) -> None:
    s = read_shape(mobility_root / shape_id)
    g = build_graph(s, n_points=64)
    _check_invariants(g, s)
    # points lie on the node's meshes
    for k, nid in enumerate(g.node_ids):
        ms = _node_meshes(s, int(nid))
        off = np.cumsum([0] + [len(m[0]) for m in ms[:-1]])
        v = np.concatenate([m[0] for m in ms])
        f = np.concatenate([m[1] + o for m, o in zip(ms, off)])
        assert _on_triangles(g.points[k].astype(np.float64), v, f, 1e-4).all()
    # sibling distances equal the brute-force minimum over leaf pairs (python-fcl)
    leaf_mesh = {}
    for k in np.flatnonzero(g.is_leaf):
        ms = _node_meshes(s, int(g.node_ids[k]))
        off = np.cumsum([0] + [len(m[0]) for m in ms[:-1]])
        leaf_mesh[k] = (np.concatenate([m[0] for m in ms]),
                        np.concatenate([m[1] + o for m, o in zip(ms, off)]))
    cap, tol = g.meta["distance_cap"], g.meta["contact_tolerance"]
    cache: dict = {}
    for (i, j), dist, contact in zip(g.sibling_edges, g.sibling_distance, g.sibling_contact):
        best = cap
        for a in g.leaves_of(int(i)):
            for b in g.leaves_of(int(j)):
                key = (min(a, b), max(a, b))
                if key not in cache:
                    cache[key] = _fcl_distance(leaf_mesh[a], leaf_mesh[b])
                best = min(best, cache[key])
        assert dist == pytest.approx(best, abs=1e-6 * g.scale)
        if abs(best - tol) > 1e-6 * g.scale:
            assert contact == (best <= tol)
