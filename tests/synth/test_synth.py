"""Tests of kinmo.synth: formats, closed meshes, axes on hinge edges, no interpenetration at
rest and at the joint limits, sign conventions, determinism, CLI.

The geometry checks are independent of the generator: meshes are read back from the written
OBJ files, containment is a generalised winding number computed with numpy, joints are
applied from ``mobility_v2.json`` with numpy.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from kinmo.synth import CATEGORIES, generate_dataset, generate_object, synthetic_id

SEED = 7
PER_CATEGORY = 2
N = PER_CATEGORY * len(CATEGORIES)

#: Semantics of hinges pivoting on an edge of the part / about the part centre / on its ends.
SIDE_HINGES = {"rotation_door", "door", "screen", "lid", "foot_pad"}
CENTRE_HINGES = {"knob", "rotation_tray"}
THROUGH_HINGES = {"handle"}  # bucket bail on its pins, safe lever on its hub


# --------------------------------------------------------------------------- reading


def load_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and zero-based triangle faces (F, 3) of an OBJ file."""
    v, f = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            idx = [int(x.split("/")[0]) - 1 for x in line.split()[1:]]
            f += [[idx[0], idx[i], idx[i + 1]] for i in range(1, len(idx) - 1)]
    return np.array(v, dtype=np.float64), np.array(f, dtype=np.int64)


class Obj:
    """A generated PartNet-Mobility folder read back with json + numpy only."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.meta = json.loads((folder / "meta.json").read_text())
        self.result = json.loads((folder / "result.json").read_text())
        self.links = json.loads((folder / "mobility_v2.json").read_text())
        self.semantics = (folder / "semantics.txt").read_text().splitlines()
        self.nodes: dict[int, dict] = {}
        self.parent_of: dict[int, int | None] = {}

        def walk(n: dict, parent: int | None) -> None:
            self.nodes[n["id"]] = n
            self.parent_of[n["id"]] = parent
            for c in n.get("children", []):
                walk(c, n["id"])

        walk(self.result[0], None)
        self._meshes: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def mesh(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in self._meshes:
            self._meshes[name] = load_obj(self.folder / "textured_objs" / f"{name}.obj")
        return self._meshes[name]

    def leaf_ids(self) -> list[int]:
        return [i for i, n in self.nodes.items() if not n.get("children")]

    def link_meshes(self, link: dict) -> list[tuple[np.ndarray, np.ndarray]]:
        return [self.mesh(o) for p in link["parts"] for o in self.nodes[p["id"]]["objs"]]

    def semantic(self, link_id: int) -> str:
        return self.semantics[link_id].split()[2]

    @property
    def diag(self) -> float:
        vs = np.concatenate(
            [self.mesh(o)[0] for i in self.leaf_ids() for o in self.nodes[i]["objs"]]
        )
        return float(np.linalg.norm(vs.max(0) - vs.min(0)))


# --------------------------------------------------------------------------- geometry


def winding_number(points: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Generalised winding number of points (P, 3) w.r.t. a closed mesh (van Oosterom)."""
    out = np.zeros(len(points))
    tri = V[F]  # (F, 3, 3)
    for s in range(0, len(points), 256):
        p = points[s : s + 256]
        a = tri[None, :, 0] - p[:, None]
        b = tri[None, :, 1] - p[:, None]
        c = tri[None, :, 2] - p[:, None]
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        num = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("pfi,pfi->pf", a, b) * lc
            + np.einsum("pfi,pfi->pf", b, c) * la
            + np.einsum("pfi,pfi->pf", c, a) * lb
        )
        out[s : s + 256] = np.arctan2(num, den).sum(axis=1) / (2 * np.pi)
    return out


def inside(points: np.ndarray, mesh: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Boolean mask of the points strictly inside a closed, outward-wound mesh."""
    V, F = mesh
    lo, hi = V.min(0), V.max(0)
    cand = np.all((points > lo) & (points < hi), axis=1)
    mask = np.zeros(len(points), dtype=bool)
    if cand.any():
        mask[cand] = winding_number(points[cand], V, F) > 0.5
    return mask


def interior_samples(
    mesh: tuple[np.ndarray, np.ndarray], n: int, eps: float, seed: int = 0
) -> np.ndarray:
    """Area-weighted surface samples pushed ``eps`` inward along the face normals."""
    V, F = mesh
    tri = V[F]
    cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(cr, axis=1)
    rng = np.random.default_rng(seed)
    fi = rng.choice(len(F), size=n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tri[fi]
    pts = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    normals = cr[fi] / area[fi, None]
    return pts - eps * normals


def transform(link: dict, value: float, turn: float = 0.0) -> np.ndarray:
    """4x4 transform of a link at joint value ``value`` (degrees or mesh units)."""
    ax = link["jointData"]["axis"]
    o = np.array(ax["origin"], dtype=np.float64)
    d = np.array(ax["direction"], dtype=np.float64)
    d /= np.linalg.norm(d)

    def rot(deg: float) -> np.ndarray:
        th = np.deg2rad(deg)
        K = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
        R = np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = o - R @ o
        return T

    if link["joint"] == "hinge":
        return rot(value)
    T = np.eye(4)
    T[:3, 3] = value * d
    return T @ rot(turn)


def moved(mesh: tuple[np.ndarray, np.ndarray], T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    V, F = mesh
    return V @ T[:3, :3].T + T[:3, 3], F


def penetration(a: list, b: list, eps: float, n: int = 300) -> float:
    """Fraction of the interior samples of meshes ``a`` lying inside some mesh of ``b``."""
    total, bad = 0, 0
    for i, ma in enumerate(a):
        pts = interior_samples(ma, n, eps, seed=i)
        hit = np.zeros(len(pts), dtype=bool)
        for mb in b:
            hit |= inside(pts, mb)
        total += len(pts)
        bad += int(hit.sum())
    return bad / max(total, 1)


def obb(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Oriented box: the axis-aligned box unless trimesh's oriented box is clearly smaller
    (trimesh's search is a heuristic, and round parts have many near-minimal boxes): centre
    (3,), unit axes (3, 3) as rows, half extents (3,)."""
    to_origin, extents = trimesh.bounds.oriented_bounds(points)
    lo, hi = points.min(0), points.max(0)
    if np.prod(hi - lo) <= 1.02 * np.prod(extents):
        return (lo + hi) / 2, np.eye(3), (hi - lo) / 2
    T = np.linalg.inv(to_origin)
    return T[:3, 3], T[:3, :3].T, np.asarray(extents) / 2


def line_distance(p: np.ndarray, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Distances of points (N, 3) to the line through ``o`` along unit ``d``."""
    r = np.atleast_2d(p) - o
    return np.linalg.norm(r - np.outer(r @ d, d), axis=1)


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    out = tmp_path_factory.mktemp("synth")
    return generate_dataset(out, N, SEED, progress=False)


@pytest.fixture(scope="module")
def objects(dataset: list[Path]) -> list[Obj]:
    return [Obj(f) for f in dataset]


# --------------------------------------------------------------------------- formats


def test_every_category_generated(objects: list[Obj]) -> None:
    cats = [o.meta["model_cat"] for o in objects]
    assert sorted(set(cats)) == sorted(CATEGORIES)
    assert all(cats.count(c) == PER_CATEGORY for c in CATEGORIES)


def test_meta_and_ids(objects: list[Obj], dataset: list[Path]) -> None:
    for k, o in enumerate(objects):
        assert list(o.meta) == [
            "model_id",
            "anno_id",
            "user_id",
            "time_in_sec",
            "version",
            "model_cat",
        ]
        assert all(isinstance(v, str) for v in o.meta.values())
        assert o.meta["anno_id"] == o.folder.name == synthetic_id(SEED, k)
        assert o.folder.name.isdigit() and len(o.folder.name) >= 11 and o.folder.name[0] == "9"
        assert len(o.meta["model_id"]) == 32
    manifest = json.loads((dataset[0].parent / f"synth-{SEED}.json").read_text())
    assert [r["id"] for r in manifest["objects"]] == [f.name for f in dataset]


def test_result_json_hierarchy(objects: list[Obj]) -> None:
    for o in objects:
        assert isinstance(o.result, list) and len(o.result) == 1
        ids = list(o.nodes)
        assert len(ids) == len(set(ids)) and sorted(ids) == list(range(len(ids)))
        assert o.result[0]["id"] == 0
        for n in o.nodes.values():
            assert set(n) in ({"text", "children", "id", "name"}, {"text", "objs", "id", "name"})
            assert n["name"] and n["text"]
            if "objs" in n:
                assert n["objs"] and all(isinstance(x, str) for x in n["objs"])
                for name in n["objs"]:
                    assert name.startswith("original-")
                    assert (o.folder / "textured_objs" / f"{name}.obj").is_file()
            else:
                assert n["children"]
        all_objs = [x for i in o.leaf_ids() for x in o.nodes[i]["objs"]]
        assert len(all_objs) == len(set(all_objs))
        assert sorted(p.stem for p in (o.folder / "textured_objs").iterdir()) == sorted(all_objs)


def test_hierarchies_are_partnet_like(objects: list[Obj]) -> None:
    depth = {
        "StorageFurniture": 3,
        "Refrigerator": 3,
        "Table": 4,
        "Microwave": 3,
        "Dishwasher": 3,
        "Laptop": 2,
        "Bottle": 2,
        "Oven": 1,
        "Bucket": 1,
        "KitchenPot": 1,
        "Safe": 1,
        "WashingMachine": 1,
        "TrashCan": 1,
    }
    roots = {
        "StorageFurniture": "storage_furniture",
        "Refrigerator": "refrigerator",
        "Oven": "Oven",
        "Microwave": "microwave",
        "Dishwasher": "dishwasher",
        "Laptop": "laptop",
        "Table": "table",
        "Bucket": "Bucket",
        "KitchenPot": "KitchenPot",
        "Bottle": "bottle",
        "Safe": "Safe",
        "WashingMachine": "WashingMachine",
        "TrashCan": "Trashcan",
    }
    for o in objects:
        cat = o.meta["model_cat"]
        assert o.result[0]["name"] == roots[cat]

        def d(i: int, parent_of: dict = o.parent_of) -> int:
            p, k = parent_of[i], 0
            while p is not None:
                p, k = parent_of[p], k + 1
            return k

        assert max(d(i) for i in o.leaf_ids()) >= depth[cat], cat
    sf = next(o for o in objects if o.meta["model_cat"] == "StorageFurniture")
    names = {n["name"] for n in sf.nodes.values()}
    assert {"cabinet", "cabinet_frame", "vertical_side_panel", "back_panel"} <= names


def test_mobility_json(objects: list[Obj]) -> None:
    for o in objects:
        links = o.links
        assert [lk["id"] for lk in links] == list(range(len(links)))
        roots = [lk for lk in links if lk["parent"] == -1]
        assert len(roots) == 1 and roots[0]["joint"] in ("heavy", "free", "static")
        assert roots[0]["jointData"] == {}
        claimed = [p["id"] for lk in links for p in lk["parts"]]
        assert sorted(claimed) == sorted(o.leaf_ids()), "every leaf in exactly one link"
        assert len(links) >= 2
        for lk in links:
            assert list(lk) == ["id", "parent", "joint", "name", "parts", "jointData"]
            for p in lk["parts"]:
                assert p["name"] == o.nodes[p["id"]]["name"] and p["children"] == []
            if lk["parent"] == -1:
                continue
            assert 0 <= lk["parent"] < len(links) and lk["joint"] in ("hinge", "slider")
            ax = lk["jointData"]["axis"]
            assert len(ax["origin"]) == 3 and len(ax["direction"]) == 3
            assert abs(np.linalg.norm(ax["direction"]) - 1) < 1e-6
            lim = lk["jointData"]["limit"]
            if lk["joint"] == "slider":
                assert set(lim) == {
                    "a",
                    "b",
                    "noLimit",
                    "rotates",
                    "noRotationLimit",
                    "rotationLimit",
                }
                assert lim["noLimit"] is False and lim["a"] <= 0 < lim["b"]
            else:
                assert set(lim) == {"a", "b", "noLimit"}
                if lim["noLimit"]:
                    assert lim["a"] == lim["b"] == 0
                else:
                    assert lim["a"] <= 0 <= lim["b"] and lim["b"] - lim["a"] >= 10
                    assert lim["b"] - lim["a"] <= 360
        sem = o.semantics
        assert len(sem) == len(links)
        for lk, line in zip(links, sem, strict=True):
            link_name, joint, label = line.split()
            assert link_name == f"link_{lk['id']}"
            rot = lk["joint"] == "slider" and lk["jointData"]["limit"]["rotates"]
            assert joint == ("slider+" if rot else lk["joint"]) and label


def test_fine_motion_types_covered(objects: list[Obj]) -> None:
    """Every moving fine type of the paper appears (R_V_S, R_H_S, R_H_C, R_V_C, P_H, P_V, PR_V)."""
    seen = set()
    for o in objects:
        for lk in o.links:
            if lk["parent"] == -1:
                continue
            d = np.abs(np.array(lk["jointData"]["axis"]["direction"]))
            hv = "V" if d[1] > 0.9 else "H"
            if lk["joint"] == "slider":
                seen.add(("PR_" if lk["jointData"]["limit"]["rotates"] else "P_") + hv)
            else:
                seen.add(f"R_{hv}_" + ("C" if o.semantic(lk["id"]) in CENTRE_HINGES else "S"))
    # a dataset of 2 per category may miss a random option (e.g. no oven tray): need the core ones
    assert {"R_V_S", "R_H_S", "R_H_C", "P_H", "P_V", "PR_V"} <= seen, seen


# --------------------------------------------------------------------------- meshes


def test_meshes_closed_and_outward(objects: list[Obj]) -> None:
    for o in objects:
        for p in sorted((o.folder / "textured_objs").iterdir()):
            V, F = load_obj(p)
            m = trimesh.Trimesh(V, F, process=False)
            assert m.is_watertight and m.is_winding_consistent, p
            assert m.volume > 0 and m.area > 0, p


def test_sizes_like_real_objects(objects: list[Obj]) -> None:
    for o in objects:
        vs = np.concatenate([o.mesh(x)[0] for i in o.leaf_ids() for x in o.nodes[i]["objs"]])
        lo, hi = vs.min(0), vs.max(0)
        assert 1.6 < np.linalg.norm(hi - lo) < 3.0
        assert np.all(np.abs((lo + hi) / 2) < 1e-5)


# --------------------------------------------------------------------------- axes


def test_axes_on_hinge_edges_and_slides_along_box_axes(objects: list[Obj]) -> None:
    for o in objects:
        tol = 1e-3 * o.diag
        for lk in o.links:
            if lk["parent"] == -1:
                continue
            ax = lk["jointData"]["axis"]
            org, d = np.array(ax["origin"]), np.array(ax["direction"])
            pts = np.concatenate([m[0] for m in o.link_meshes(lk)])
            c, axes, half = obb(pts)
            cos = np.abs(axes @ d)
            i = int(np.argmax(cos))
            assert cos[i] > 0.999, (o.folder.name, lk["name"], "axis not along a box axis")
            sem = o.semantic(lk["id"])
            if lk["joint"] == "slider" or sem in CENTRE_HINGES:
                if lk["joint"] == "hinge" or lk["jointData"]["limit"]["rotates"]:
                    assert line_distance(c, org, d)[0] < tol, (
                        o.folder.name,
                        lk["name"],
                        "off-centre",
                    )
                continue
            if sem in SIDE_HINGES:
                # on an edge of the part's box, or of the box of one of its meshes (a door
                # hinged on its front edge with a handle protruding in front of it)
                dist = np.inf
                for cc, aa, hh in [(c, axes, half)] + [obb(m[0]) for m in o.link_meshes(lk)]:
                    ii = int(np.argmax(np.abs(aa @ d)))
                    if abs(aa[ii] @ d) < 0.999:
                        continue
                    j, k = [x for x in range(3) if x != ii]
                    edges = np.array(
                        [
                            cc + sj * hh[j] * aa[j] + sk * hh[k] * aa[k]
                            for sj in (-1, 1)
                            for sk in (-1, 1)
                        ]
                    )
                    dist = min(dist, line_distance(edges, org, d).min())
                assert dist < tol, (o.folder.name, lk["name"], dist)
            else:
                # the axis runs through the handle's material: a bucket bail on the pins at
                # both of its ends, a safe lever through its hub
                assert sem in THROUGH_HINGES, sem
                proj = (pts - org) @ d
                ts = np.linspace(proj.min() - 1e-3, proj.max() + 1e-3, 401)
                mid = (proj.min() + proj.max()) / 2
                on_axis = org + np.outer(ts, d)
                hit = np.zeros(len(ts), dtype=bool)
                for m in o.link_meshes(lk):
                    hit |= inside(on_axis, m)
                assert hit.any(), (o.folder.name, lk["name"])
                if o.meta["model_cat"] == "Bucket":
                    assert hit[ts < mid].any() and hit[ts > mid].any(), (o.folder.name, lk["name"])


def test_positive_motion_opens(objects: list[Obj]) -> None:
    for o in objects:
        for lk in o.links:
            if lk["parent"] == -1:
                continue
            sem = o.semantic(lk["id"])
            d = np.array(lk["jointData"]["axis"]["direction"])
            if lk["joint"] == "slider":
                up = sem in ("lid", "rotation_lid")
                assert np.dot(d, [0, 1, 0] if up else [0, 0, 1]) > 0.999, (o.folder.name, sem)
            elif sem in ("rotation_door", "door"):
                pts = np.concatenate([m[0] for m in o.link_meshes(lk)])
                T = transform(lk, 10.0)
                assert (pts @ T[:3, :3].T + T[:3, 3])[:, 2].mean() > pts[:, 2].mean() + 1e-3
            elif sem == "lid":  # a hinged lid lifts
                pts = np.concatenate([m[0] for m in o.link_meshes(lk)])
                T = transform(lk, 10.0)
                assert (pts @ T[:3, :3].T + T[:3, 3])[:, 1].mean() > pts[:, 1].mean() + 1e-3
            elif sem == "screen":  # opening tilts the lid further back (-z)
                pts = np.concatenate([m[0] for m in o.link_meshes(lk)])
                T = transform(lk, 5.0)
                assert (pts @ T[:3, :3].T + T[:3, 3])[:, 2].mean() < pts[:, 2].mean()


# --------------------------------------------------------------------------- interpenetration


def test_no_interpenetration_at_rest(objects: list[Obj]) -> None:
    for o in objects:
        eps = 1e-4 * o.diag
        leaves = o.leaf_ids()
        meshes = {i: [o.mesh(x) for x in o.nodes[i]["objs"]] for i in leaves}
        boxes = {
            i: (np.min([m[0].min(0) for m in ms], 0), np.max([m[0].max(0) for m in ms], 0))
            for i, ms in meshes.items()
        }
        for a in leaves:
            for b in leaves:
                if a == b:
                    continue
                (la, ha), (lb, hb) = boxes[a], boxes[b]
                if np.any(la >= hb) or np.any(lb >= ha):
                    continue
                frac = penetration(meshes[a], meshes[b], eps, n=200)
                assert frac == 0.0, (o.folder.name, o.nodes[a]["name"], o.nodes[b]["name"], frac)


def test_no_interpenetration_at_limits(objects: list[Obj]) -> None:
    worst = 0.0
    for o in objects:
        eps = 1e-4 * o.diag
        by_id = {lk["id"]: lk for lk in o.links}
        for lk in o.links:
            if lk["parent"] == -1:
                continue
            lim = lk["jointData"]["limit"]
            if lk["joint"] == "hinge" and lim["noLimit"]:
                poses = [(90.0, 0.0), (180.0, 0.0), (270.0, 0.0)]
            else:
                poses = [(lim["a"], 0.0), (lim["b"], 0.0), ((lim["a"] + lim["b"]) / 2, 0.0)]
                if lk["joint"] == "slider" and lim["rotates"]:
                    poses += [(lim["b"] / 2, 90.0), (0.0, 45.0)]
            parent = o.link_meshes(by_id[lk["parent"]])
            for value, turn in poses:
                T = transform(lk, value, turn)
                part = [moved(m, T) for m in o.link_meshes(lk)]
                frac = max(penetration(part, parent, eps, 150), penetration(parent, part, eps, 60))
                worst = max(worst, frac)
                assert frac < 0.01, (o.folder.name, lk["name"], value, turn, frac)
    assert worst < 1e-3  # in practice none at all


# --------------------------------------------------------------------------- determinism, formats


def _digest(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_same_seed_same_bytes(dataset: list[Path], tmp_path: Path) -> None:
    a = generate_dataset(tmp_path / "a", 10, SEED, progress=False)
    b = generate_dataset(tmp_path / "b", 10, SEED, progress=False)
    assert _digest(tmp_path / "a") == _digest(tmp_path / "b")
    # objects do not depend on n: the first 10 objects of the fixture run are the same
    full = {f.name: f for f in dataset}
    for f in a:
        assert _digest(f) == _digest(full[f.name])
    assert [f.name for f in a] == [f.name for f in b]


def test_different_seeds_differ(tmp_path: Path) -> None:
    for cat in CATEGORIES:
        o1, o2 = generate_object(cat, 1, 0), generate_object(cat, 2, 0)
        v1 = np.concatenate([m.vertices for m in o1.root.all_meshes()])
        v2 = np.concatenate([m.vertices for m in o2.root.all_meshes()])
        assert v1.shape != v2.shape or not np.allclose(v1, v2), cat
    a = generate_dataset(tmp_path / "a", 3, 1, progress=False)
    b = generate_dataset(tmp_path / "b", 3, 2, progress=False)
    assert {f.name for f in a}.isdisjoint(f.name for f in b)


def test_partnet_format(tmp_path: Path) -> None:
    folders = generate_dataset(tmp_path, 4, 3, partnet=True, progress=False)
    for f in folders:
        assert sorted(p.name for p in f.iterdir()) == ["meta.json", "objs", "result.json"]
        res = json.loads((f / "result.json").read_text())
        objs = []
        stack = [res[0]]
        while stack:
            n = stack.pop()
            stack += n.get("children", [])
            objs += n.get("objs", [])
        assert sorted(p.stem for p in (f / "objs").iterdir()) == sorted(objs)
    # same geometry as the PartNet-Mobility output of the same seed
    mob = generate_dataset(tmp_path / "mob", 4, 3, progress=False)
    for f, g in zip(folders, mob, strict=True):
        assert (f / "result.json").read_bytes() == (g / "result.json").read_bytes()
        assert _digest(f / "objs") == _digest(g / "textured_objs")


def test_rewrite_replaces_folder(tmp_path: Path) -> None:
    (f,) = generate_dataset(tmp_path, 1, 5, progress=False)
    (f / "textured_objs" / "stale.obj").write_text("x")
    generate_dataset(tmp_path, 1, 5, progress=False)
    assert not (f / "textured_objs" / "stale.obj").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unknown categories"):
        generate_dataset(tmp_path, 1, 0, categories=["Chair"], progress=False)
    with pytest.raises(ValueError):
        generate_dataset(tmp_path, -1, 0, progress=False)
    with pytest.raises(ValueError):
        synthetic_id(-1, 0)


def test_cli(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from kinmo.cli import app

    r = CliRunner().invoke(
        app,
        [
            "synth",
            str(tmp_path / "o"),
            "--n",
            "3",
            "--seed",
            "4",
            "--categories",
            "Laptop",
            "--categories",
            "Bottle",
        ],
    )
    assert r.exit_code == 0, r.output
    cats = sorted(
        json.loads((f / "meta.json").read_text())["model_cat"]
        for f in (tmp_path / "o").iterdir()
        if f.is_dir()
    )
    assert cats in (["Bottle", "Bottle", "Laptop"], ["Bottle", "Laptop", "Laptop"])
    r = CliRunner().invoke(app, ["synth", str(tmp_path / "p"), "--n", "1", "--partnet"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "p" / synthetic_id(0, 0) / "objs").is_dir()
    r = CliRunner().invoke(app, ["synth", str(tmp_path / "q"), "--categories", "Chair"])
    assert r.exit_code != 0 and "Chair" in r.output


# --------------------------------------------------------------------------- other modules


def test_folders_read_back_with_kinmo_readers(
    objects: list[Obj], dataset: list[Path], tmp_path: Path
) -> None:
    from kinmo.data.model import JointType, ShapeFormat
    from kinmo.data.readers import find_shapes, read_shape

    assert find_shapes(dataset[0].parent) == sorted(dataset)
    for o in objects:
        shape = read_shape(o.folder)
        assert shape.format is ShapeFormat.PARTNET_MOBILITY
        assert shape.id == o.folder.name and shape.category == o.meta["model_cat"]
        assert sorted(shape.hierarchy.nodes) == sorted(o.nodes)
        assert len(shape.links) == len(o.links)
        for link, raw in zip(sorted(shape.links, key=lambda x: x.id), o.links, strict=True):
            assert link.parent == raw["parent"] and link.name == raw["name"]
            assert sorted(link.parts) == sorted(p["id"] for p in raw["parts"])
            assert link.joint.type is JointType(raw["joint"])
            if link.joint.is_moving:
                ax = raw["jointData"]["axis"]
                np.testing.assert_allclose(link.joint.origin, ax["origin"])
                np.testing.assert_allclose(link.joint.direction, ax["direction"], atol=1e-9)
                lim = raw["jointData"]["limit"]
                if lim["noLimit"]:
                    assert link.joint.limit is None
                else:
                    assert tuple(link.joint.limit) == (lim["a"], lim["b"])
                assert link.joint.rotates == bool(lim.get("rotates", False))
    for f in generate_dataset(tmp_path, 3, 9, partnet=True, progress=False):
        shape = read_shape(f)
        assert shape.format is ShapeFormat.PARTNET and shape.links is None


def test_ground_truth_fine_types(dataset: list[Path]) -> None:
    """kinmo's labelling (Liu et al. Sec. 3.1) recovers the intended fine type of each part."""
    from kinmo.data.build import build_graph
    from kinmo.data.model import FINE_TYPES
    from kinmo.data.readers import read_shape

    expected = {  # (moving node name, fine types it may get)
        "cabinet_door": {"R_V_S", "R_H_S"},
        "door": {"R_V_S", "R_H_S"},
        "drawer": {"P_H"},
        "knob": {"R_H_C"},
        "control_button": {"R_H_C"},
        "switch": {"R_H_C"},
        "button": {"R_H_C"},
        "screen_side": {"R_H_S"},
        "handle": {"R_H_S"},
        "lid": {"P_V", "PR_V", "R_H_S"},
        "tray": {"P_H"},
        "foot_pad": {"R_H_S"},
    }
    seen: dict[str, set[str]] = {}
    for f in dataset:
        g = build_graph(read_shape(f), n_points=64)
        for k, (i, _) in enumerate(g.sibling_edges):
            t = FINE_TYPES[g.edge_fine[k]]
            if t not in ("None", "Fixed"):
                seen.setdefault(g.node_names[i], set()).add(t)
    for name, types in seen.items():
        if name in expected:
            assert types <= expected[name], (name, types)
    assert {"cabinet_door", "door", "drawer", "knob", "screen_side", "handle", "lid"} <= set(seen)
    assert "PR_V" in seen["lid"] and "P_V" in seen["lid"]


def test_urdf_loads_in_pybullet_and_joints_reach_limits(objects: list[Obj], tmp_path: Path) -> None:
    import pybullet as pb

    from kinmo.data.readers import read_shape
    from kinmo.urdf import write_urdf

    def quat_matrix(q: tuple) -> np.ndarray:
        return np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)

    firsts = {}
    for o in objects:
        firsts.setdefault(o.meta["model_cat"], o)
    cid = pb.connect(pb.DIRECT)
    try:
        for o in firsts.values():
            path = write_urdf(read_shape(o.folder), tmp_path / f"{o.folder.name}.urdf")
            body = pb.loadURDF(str(path), useFixedBase=True, physicsClientId=cid)
            joints = {}
            for j in range(pb.getNumJoints(body, physicsClientId=cid)):
                info = pb.getJointInfo(body, j, physicsClientId=cid)
                joints[info[1].decode()] = (j, info[2], info[8], info[9], info[12].decode())
            moving = [lk for lk in o.links if lk["parent"] != -1]
            assert moving
            for lk in moving:
                lim = lk["jointData"]["limit"]
                j, jtype, lo, hi, child = joints[f"joint_{lk['id']}"]
                rot_j = joints.get(f"joint_{lk['id']}_rotation")
                link_index = rot_j[0] if rot_j else j
                if lk["joint"] == "hinge":
                    assert jtype == pb.JOINT_REVOLUTE
                    if lim["noLimit"]:
                        values = [-np.pi / 2, np.pi / 2]
                    else:
                        assert np.allclose([lo, hi], np.deg2rad([lim["a"], lim["b"]]))
                        values = [lo, hi]
                    to_mob = np.rad2deg
                else:
                    assert jtype == pb.JOINT_PRISMATIC and np.allclose(
                        [lo, hi], [lim["a"], lim["b"]]
                    )
                    values, to_mob = [lo, hi], (lambda v: v)
                a = np.array(lk["jointData"]["axis"]["origin"])
                for q in values:
                    turn = 0.0
                    pb.resetJointState(body, j, q, physicsClientId=cid)
                    if rot_j:
                        turn = lim["rotationLimit"] if not lim["noRotationLimit"] else 90.0
                        pb.resetJointState(body, rot_j[0], np.deg2rad(turn), physicsClientId=cid)
                    assert abs(pb.getJointState(body, j, physicsClientId=cid)[0] - q) < 1e-9
                    st = pb.getLinkState(
                        body, link_index, computeForwardKinematics=True, physicsClientId=cid
                    )
                    T = transform(lk, to_mob(q), turn)
                    np.testing.assert_allclose(st[4], T[:3, :3] @ a + T[:3, 3], atol=1e-5)
                    np.testing.assert_allclose(quat_matrix(st[5]), T[:3, :3], atol=1e-5)
                pb.resetJointState(body, j, 0.0, physicsClientId=cid)
                if rot_j:
                    pb.resetJointState(body, rot_j[0], 0.0, physicsClientId=cid)
    finally:
        pb.disconnect(cid)
