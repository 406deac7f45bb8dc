"""Area-weighted surface sampling (:mod:`kinmo.geometry.sampling`, Rust)."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from kinmo import _core
from kinmo.geometry import load_obj, sample_surface, sample_surface_groups

M64 = (1 << 64) - 1


# --- an independent pure-Python model of the documented algorithm ----------------------


def _splitmix64(state: int) -> tuple[int, int]:
    state = (state + 0x9E3779B97F4A7C15) & M64
    z = state
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & M64
    return state, z ^ (z >> 31)


def _rotl(x: int, k: int) -> int:
    return ((x << k) | (x >> (64 - k))) & M64


class _Xoshiro256pp:
    def __init__(self, seed: int):
        self.s = []
        st = seed
        for _ in range(4):
            st, z = _splitmix64(st)
            self.s.append(z)

    def next_u64(self) -> int:
        s = self.s
        result = (_rotl((s[0] + s[3]) & M64, 23) + s[0]) & M64
        t = (s[1] << 17) & M64
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = _rotl(s[3], 45)
        return result

    def next_f64(self) -> float:
        return (self.next_u64() >> 11) * (1.0 / (1 << 53))


def _reference_sample(v: np.ndarray, f: np.ndarray, n: int, seed: int):
    """Vose's alias table (32-bit integer draw) + Osada's sqrt formula, in plain Python."""
    weights, ids, total = [], [], 0.0
    for k, (i, j, m) in enumerate(f.tolist()):
        a, b, c = (v[i].tolist(), v[j].tolist(), v[m].tolist())
        e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]]
        e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]]
        x = e1[1] * e2[2] - e1[2] * e2[1]
        y = e1[2] * e2[0] - e1[0] * e2[2]
        z = e1[0] * e2[1] - e1[1] * e2[0]
        area = 0.5 * math.sqrt(x * x + y * y + z * z)
        if area > 0:
            total += area
            weights.append(area)
            ids.append(k)
    K = len(weights)
    scale = K / total
    weights = [w * scale for w in weights]
    # Keep thresholds in units of 2**-32; 2**32 means "always keep".
    keep, alias = [1 << 32] * K, list(range(K))
    small = [i for i in range(K) if weights[i] < 1.0]
    large = [i for i in range(K) if weights[i] >= 1.0]
    while small and large:
        lo, g = small.pop(), large[-1]
        keep[lo], alias[lo] = int(weights[lo] * 4294967296.0), g
        weights[g] = (weights[g] + weights[lo]) - 1.0
        if weights[g] < 1.0:
            large.pop()
            small.append(g)
    rng = _Xoshiro256pp(seed)
    pts, faces = [], []
    for _ in range(n):
        r = rng.next_u64()
        col = ((r >> 32) * K) >> 32
        face = ids[col if (r & 0xFFFFFFFF) < keep[col] else alias[col]]
        a, b, c = (v[q].tolist() for q in f[face])
        s = math.sqrt(rng.next_f64())
        r2 = rng.next_f64()
        pts.append([a[d] * (1.0 - s) + b[d] * (s * (1.0 - r2)) + c[d] * (s * r2) for d in range(3)])
        faces.append(face)
    return np.array(pts), np.array(faces)


# --- helpers -----------------------------------------------------------------------------


def _tri_mesh():
    """Two triangles of areas 0.5 and 1.5, plus a collinear and a repeated-vertex face."""
    v = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 0, 1], [0, 1, 1], [2, 0, 0]], float
    )
    f = np.array([[0, 1, 2], [0, 1, 6], [3, 4, 5], [2, 2, 5]])
    return v, f


def _area(v, f):
    t = v[f]
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


def _on_face(points, v, f, face_index, scale):
    """Max distance to the face plane and min barycentric coordinate, relative to ``scale``."""
    t = v[f[face_index]]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    area2 = np.linalg.norm(n, axis=1)
    nu = n / area2[:, None]
    dist = np.abs(np.einsum("ij,ij->i", points - t[:, 0], nu))
    w0 = np.einsum("ij,ij->i", np.cross(t[:, 1] - points, t[:, 2] - points), nu) / area2
    w1 = np.einsum("ij,ij->i", np.cross(t[:, 2] - points, t[:, 0] - points), nu) / area2
    w2 = 1 - w0 - w1
    return dist.max() / scale, min(w0.min(), w1.min(), w2.min())


def _point_mesh_distance(points: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Exact distance of each point to a triangle mesh (brute force over faces, numpy).

    Closest point on each triangle by the region tests of Ericson, *Real-Time Collision
    Detection* (2005) Sec. 5.1.5; an independent check of the Rust sampler.
    """
    out = np.full(len(points), np.inf)
    a, b, c = (v[f[:, k]][None] for k in range(3))  # (1, F, 3)
    for i0 in range(0, len(points), 32):
        p = points[i0 : i0 + 32, None, :]  # (P, 1, 3)
        ab, ac, ap = b - a, c - a, p - a
        d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
        bp = p - b
        d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
        cp = p - c
        d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
        va = d3 * d6 - d5 * d4
        vb = d5 * d2 - d1 * d6
        vc = d1 * d4 - d3 * d2
        with np.errstate(divide="ignore", invalid="ignore"):
            denom = va + vb + vc
            v_in, w_in = vb / denom, vc / denom
            q = a + ab * v_in[..., None] + ac * w_in[..., None]  # face region
            t_ab = d1 / (d1 - d3)
            t_ac = d2 / (d2 - d6)
            t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        regions = [
            ((d1 <= 0) & (d2 <= 0), np.broadcast_to(a, q.shape)),
            ((d3 >= 0) & (d4 <= d3), np.broadcast_to(b, q.shape)),
            ((d6 >= 0) & (d5 <= d6), np.broadcast_to(c, q.shape)),
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[..., None]),
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[..., None]),
            ((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), b + (c - b) * t_bc[..., None]),
        ]
        for mask, target in reversed(regions):
            q = np.where(mask[..., None], target, q)
        d = np.linalg.norm(p - q, axis=-1)
        d = np.where(np.isfinite(d), d, np.inf)
        out[i0 : i0 + 32] = d.min(1)
    return out


@pytest.fixture(scope="module")
def real_parts(mobility_root: Path):
    paths = sorted(mobility_root.glob("*/textured_objs/*.obj"))[::400]
    return [load_obj(p) for p in paths]


# --- tests -------------------------------------------------------------------------------


def test_shapes_and_dtypes():
    v, f = _tri_mesh()
    p, fi = sample_surface(v, f.astype(np.int32), 17, seed=3)
    assert p.shape == (17, 3) and p.dtype == np.float64
    assert fi.shape == (17,) and fi.dtype == np.int64


def test_bit_identical_to_the_documented_algorithm():
    """Portable RNG: the Rust output equals a pure-Python model bit for bit."""
    rng = np.random.default_rng(0)
    rv = rng.normal(size=(40, 3))
    rf = rng.integers(0, 40, size=(80, 3))
    rf[::7, 2] = rf[::7, 1]  # some zero-area faces in between
    for v, f in (_tri_mesh(), (rv, rf)):
        for seed in (0, 1, 2**64 - 1):
            p, fi = sample_surface(v, f, 200, seed)
            ref_p, ref_f = _reference_sample(v, f, 200, seed)
            np.testing.assert_array_equal(fi, ref_f)
            np.testing.assert_array_equal(p, ref_p)


def test_deterministic_and_seed_dependent():
    v, f = _tri_mesh()
    a = sample_surface(v, f, 100, 5)
    b = sample_surface(v, f, 100, 5)
    c = sample_surface(v, f, 100, 6)
    np.testing.assert_array_equal(a[0], b[0])
    assert not np.array_equal(a[0], c[0])


def test_points_on_real_surfaces(real_parts):
    for v, f in real_parts:
        p, fi = sample_surface(v, f, 1024, 0)
        scale = np.linalg.norm(v.max(0) - v.min(0))
        dist, wmin = _on_face(p, v, f, fi, scale)
        assert dist < 1e-9 and wmin > -1e-9
        # Independent check: exact point-to-mesh distance.
        assert _point_mesh_distance(p[:64], v, f).max() < 1e-9 * scale


def test_zero_area_faces_never_chosen_and_area_weighting():
    v, f = _tri_mesh()
    n = 50_000
    _, fi = sample_surface(v, f, n, 11)
    counts = np.bincount(fi, minlength=4)
    assert counts[1] == 0 and counts[3] == 0
    # Face 2 holds 0.75 of the area; binomial sd 0.0019.
    assert abs(counts[2] / n - 0.75) < 0.01


def test_area_weighting_matches_trimesh_on_a_real_part(real_parts):
    """Per-face hit rates equal the area shares, like trimesh's sampler (chi-square)."""
    v, f = max(real_parts, key=lambda m: len(m[1]))
    t = v[f]
    areas = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    probs = areas / areas.sum()
    # Bin faces into 20 equal-probability bins so every bin has many expected hits.
    order = np.argsort(probs)
    bins = np.minimum((np.cumsum(probs[order]) * 20).astype(int), 19)
    face_bin = np.empty(len(f), int)
    face_bin[order] = bins
    expected = np.bincount(face_bin, weights=probs, minlength=20)
    n = 40_000

    def chi2(fi):
        obs = np.bincount(face_bin[fi], minlength=20)
        return float((((obs - n * expected) ** 2) / (n * expected)).sum())

    ours = chi2(sample_surface(v, f, n, 1)[1])
    _, tfi = trimesh.sample.sample_surface(trimesh.Trimesh(v, f, process=False), n, seed=1)
    theirs = chi2(tfi)
    # 19 degrees of freedom: the 99.99% quantile is about 50.
    assert ours < 50 and theirs < 50, (ours, theirs)
    # Mean point = area-weighted centroid (4-sigma band of the mean).
    p = sample_surface(v, f, n, 2)[0]
    centroid = (probs[:, None] * t.mean(1)).sum(0)
    sd = p.std(0) / math.sqrt(n)
    assert np.all(np.abs(p.mean(0) - centroid) < 4 * sd + 1e-12)


def test_non_contiguous_inputs_to_core():
    v, f = _tri_mesh()
    a = _core.sample_surface(v, f, 32, 4)
    b = _core.sample_surface(np.asfortranarray(v), np.asfortranarray(f), 32, 4)
    np.testing.assert_array_equal(a[0], b[0])


_NAN_V = np.array([[0, 0, 0], [1, np.nan, 0], [0, 1, 0]])
_INF_V = np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]])
_LINE_V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)


@pytest.mark.parametrize(
    ("v", "f", "n", "seed", "match"),
    [
        (np.zeros((3, 2)), np.array([[0, 1, 2]]), 4, 0, r"vertices: expected shape \(N, 3\)"),
        (np.eye(3), np.array([[0, 1, 2, 0]]), 4, 0, r"faces: expected shape \(F, 3\)"),
        (_NAN_V, np.array([[0, 1, 2]]), 4, 0, "non-finite value at index 4"),
        (_INF_V, np.array([[0, 1, 2]]), 4, 0, "non-finite"),
        (np.eye(3), np.array([[0, -1, 2]]), 4, 0, "face 0 references vertex -1"),
        (np.eye(3), np.array([[0, 1, 3]]), 4, 0, "references vertex 3, but there are only 3"),
        (np.zeros((0, 3)), np.zeros((0, 3), int), 4, 0, "total area 0"),
        (_LINE_V, np.array([[0, 1, 2]]), 4, 0, "total area 0"),
        (np.eye(3), np.array([[0, 1, 2]]), 0, 0, "n: the number of points must be >= 1"),
        (np.eye(3), np.array([[0, 1, 2]]), -5, 0, ">= 1"),
        (np.eye(3), np.array([[0, 1, 2]]), 4, -1, r"seed: must be in \[0, 2\*\*64\)"),
        (np.eye(3), np.array([[0, 1, 2]]), 4, 2**64, "seed"),
    ],
)
def test_bad_inputs_are_valueerrors(v, f, n, seed, match):
    with pytest.raises(ValueError, match=match):
        sample_surface(v, f, n, seed)


def test_groups_shapes_union_and_single_group_equivalence(real_parts):
    meshes = real_parts[:3]
    groups = [[0], [1], [2], [0, 1, 2]]
    out = sample_surface_groups(meshes, groups, 256, seed=7)
    assert out.shape == (4, 256, 3) and out.dtype == np.float64
    # Each single-mesh group lies on its mesh; the union group hits every member.
    owners = []
    for k, (v, f) in enumerate(meshes):
        scale = np.linalg.norm(v.max(0) - v.min(0))
        assert _point_mesh_distance(out[k][:64], v, f).max() < 1e-9 * scale
        owners.append(_point_mesh_distance(out[3], v, f) < 1e-9 * scale)
    owners = np.array(owners)
    assert owners.any(0).all()  # every union point lies on a member
    # Hits per member follow the members' area shares (5-sigma binomial band).
    areas = np.array([_area(v, f) for v, f in meshes])
    share = areas / areas.sum()
    hits = owners.sum(1)
    assert np.all(np.abs(hits - 256 * share) <= 5 * np.sqrt(256 * share * (1 - share)) + 1)
    # Deterministic, seed-dependent, and group g does not depend on the other groups.
    np.testing.assert_array_equal(out, sample_surface_groups(meshes, groups, 256, seed=7))
    assert not np.array_equal(out, sample_surface_groups(meshes, groups, 256, seed=8))
    np.testing.assert_array_equal(out[:1], sample_surface_groups(meshes, groups[:1], 256, seed=7))


def test_groups_independent_of_thread_count(mobility_root):
    code = (
        "import sys, numpy as np\n"
        "from kinmo.geometry import load_obj, sample_surface_groups\n"
        "ms = [load_obj(p) for p in sys.argv[1:]]\n"
        "out = sample_surface_groups(ms, [[0], [1], [0, 1], [1, 0]] * 8, 128, 3)\n"
        "sys.stdout.write(out.tobytes().hex())\n"
    )
    paths = [str(p) for p in sorted(mobility_root.glob("*/textured_objs/*.obj"))[:2]]
    outs = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        cmd = [sys.executable, "-c", code, *paths]
        r = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        outs.append(r.stdout)
    assert outs[0] == outs[1] and len(outs[0]) == 32 * 128 * 3 * 8 * 2


@pytest.mark.parametrize(
    ("groups", "match"),
    [
        ([[0], []], r"groups\[1\] is empty"),
        ([[0, 2]], r"groups\[0\] references mesh 2, but there are only 2 meshes"),
        ([[-1]], r"groups\[0\] references mesh -1"),
        ([[1]], r"groups\[0\]: cannot sample a surface of total area 0"),
    ],
)
def test_group_errors(groups, match):
    v, f = _tri_mesh()
    flat = (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match=match):
        sample_surface_groups([(v, f), flat], groups, 8)


def test_group_bad_mesh_named_by_index():
    v, f = _tri_mesh()
    bad = (v, np.array([[0, 1, 9]]))
    with pytest.raises(ValueError, match=r"meshes\[1\] faces: face 0 references vertex 9"):
        sample_surface_groups([(v, f), bad], [[0]], 8)
    with pytest.raises(ValueError, match=r"meshes\[0\] vertices: expected shape"):
        _core.sample_surface_groups([(np.zeros((3, 2)), f)], [[0]], 8, 0)
    with pytest.raises(ValueError, match=r"meshes\[0\]: expected a \(vertices"):
        _core.sample_surface_groups([(v,)], [[0]], 8, 0)
