"""OBB fitting (:mod:`kinmo.geometry.obb`, Rust) against ``trimesh.bounds.oriented_bounds``.

Real parts: every leaf mesh (OBJ) of 30 PartNet-Mobility objects, and the union of the meshes
of every leaf part of ``result.json`` for 10 objects. Every box must contain its points
(1e-9 of the part's size), be canonical (orthonormal right-handed rows, half-extents
non-increasing, rows 0 and 1 with a positive largest component) and have a volume at most
1.01 times trimesh's minimum-volume box. *Flat* parts (box thinner than 1e-4 of its longest
side, whose thickness is rounding noise of the OBJ coordinates) compare the in-plane area
instead. Tighter boxes must exist on a fair share of the parts.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from kinmo.geometry import OBB, fit_obb, fit_obb_batch, load_obj, load_objs

FLAT = 1e-4


def _objects(mobility_root: Path, step: int) -> list[Path]:
    return sorted(p for p in mobility_root.iterdir() if p.is_dir())[::step]


@pytest.fixture(scope="module")
def leaf_meshes(mobility_root: Path) -> list[tuple[str, np.ndarray]]:
    """``(name, vertices)`` of every OBJ of 30 objects (every third one)."""
    objects = _objects(mobility_root, 3)[:30]
    assert len(objects) == 30
    paths = [p for o in objects for p in sorted((o / "textured_objs").glob("*.obj"))]
    return [(f"{p.parents[1].name}/{p.name}", v) for p, (v, _) in zip(paths, load_objs(paths))]


def _leaf_parts(node: dict) -> list[dict]:
    kids = node.get("children") or []
    return [node] if not kids else [leaf for k in kids for leaf in _leaf_parts(k)]


@pytest.fixture(scope="module")
def part_unions(mobility_root: Path) -> list[tuple[str, np.ndarray]]:
    """``(name, vertices)`` of the union of the meshes of each ``result.json`` leaf part."""
    out = []
    for obj in _objects(mobility_root, 11):
        tree = json.loads((obj / "result.json").read_text())
        for root in tree:
            for leaf in _leaf_parts(root):
                objs = leaf.get("objs") or []
                if not objs:
                    continue
                vs = [load_obj(obj / "textured_objs" / f"{name}.obj")[0] for name in objs]
                out.append((f"{obj.name}:{leaf['id']}", np.concatenate(vs)))
    assert len(out) >= 30
    return out


def _check_canonical(b: OBB) -> None:
    a = b.axes
    assert a.shape == (3, 3) and b.center.shape == (3,) and b.half_extents.shape == (3,)
    assert np.abs(a @ a.T - np.eye(3)).max() < 1e-12
    assert np.allclose(np.cross(a[0], a[1]), a[2], atol=1e-12)
    h = b.half_extents
    # Non-increasing, up to the documented tie of 1e-6 of the largest half-extent (tied
    # rows are ordered by direction instead).
    tie = 1e-6 * h[0]
    assert np.all(h >= 0) and h[0] >= h[1] - tie and h[1] >= h[2] - tie
    for row in a[:2]:
        k = int(np.argmax(np.abs(row)))
        assert row[k] > 0 or np.isclose(abs(row[k]), np.abs(row)).sum() > 1


def _compare_with_trimesh(items: list[tuple[str, np.ndarray]]) -> dict[str, int]:
    counts = {"parts": 0, "tighter": 0, "flat": 0, "trimesh_failed": 0}
    failures = []
    for name, v in items:
        if len(v) == 0:
            continue
        b = fit_obb(v)
        _check_canonical(b)
        size = float(np.linalg.norm(v.max(0) - v.min(0)))
        outside = np.abs(b.to_local(v)) - b.half_extents
        if outside.max() > 1e-9 * size:
            failures.append(f"{name}: point outside by {outside.max():.3g} (size {size:.3g})")
        try:
            with np.errstate(all="ignore"):  # trimesh divides by zero on flat parts
                _, ext = trimesh.bounds.oriented_bounds(v)
        except Exception:  # trimesh fails on a few degenerate parts; kinmo must not
            counts["trimesh_failed"] += 1
            continue
        ext = np.sort(ext)[::-1]
        h = b.half_extents
        counts["parts"] += 1
        if h[2] < FLAT * h[0]:
            counts["flat"] += 1
            ours, theirs = 4 * h[0] * h[1], ext[0] * ext[1]
        else:
            ours, theirs = b.volume, float(np.prod(ext))
        if ours > 1.01 * theirs * (1 + 1e-12):
            failures.append(f"{name}: {ours:.6g} > 1.01 x trimesh {theirs:.6g}")
        if ours < 0.999 * theirs:
            counts["tighter"] += 1
    assert not failures, failures[:10]
    return counts


def test_leaf_meshes_are_contained_and_at_least_as_tight_as_trimesh(leaf_meshes):
    c = _compare_with_trimesh(leaf_meshes)
    print(f"leaf meshes: {c}")
    assert c["parts"] >= 1000
    # The full face-flush family plus the refinement finds tighter boxes (> 0.1%) on a
    # share of the parts (12% of the whole dataset, 4% of this subset), up to 25x smaller
    # where trimesh's normals rounded to 0.1 rad miss a thin part's plane.
    assert c["tighter"] >= 0.03 * c["parts"], c


def test_part_unions_are_contained_and_at_least_as_tight_as_trimesh(part_unions):
    c = _compare_with_trimesh(part_unions)
    print(f"part unions: {c}")
    assert c["tighter"] >= 1, c


def test_up_alignment_is_preferred_on_real_parts(leaf_meshes):
    """Where the axis-aligned box is within 0.9% of the smallest box found, the chosen box
    has an axis exactly along +y (the up rule), and it is never more than 1% larger."""
    checked = considered = 0
    for name, v in leaf_meshes[::3]:
        if len(v) < 4:
            continue
        tight = fit_obb(v, volume_tolerance=0.0, up=None, symmetry=False)
        if tight.half_extents[2] < FLAT * tight.half_extents[0]:
            continue
        considered += 1
        aabb = float(np.prod(v.max(0) - v.min(0)))
        b = fit_obb(v)
        assert b.volume <= 1.01 * tight.volume * (1 + 1e-12), name
        if aabb <= 1.009 * tight.volume:
            checked += 1
            assert np.abs(b.axes[:, 1]).max() >= 1 - 1e-12, (name, b.axes)
    # Not vacuous, whichever objects the shared data holds: real PartNet-Mobility parts are
    # mostly modelled axis-aligned in the y-up frame, so a good share of the parts sampled
    # (about 30 % on the 235 objects of 2026-11) reach the rule.
    assert considered >= 100 and checked >= considered // 5, (checked, considered)


def test_result_is_independent_of_point_order_and_duplicates(leaf_meshes):
    rng = np.random.default_rng(0)
    big = sorted(leaf_meshes, key=lambda x: -len(x[1]))[:20:2]
    for name, v in big:
        b = fit_obb(v)
        perm = rng.permutation(len(v))
        shuffled = np.concatenate([v[perm], v[perm[:7]]])
        b2 = fit_obb(shuffled)
        for x, y in zip(b, b2):
            assert np.array_equal(x, y), name


def test_batch_matches_single_fits(leaf_meshes):
    items = [v for _, v in leaf_meshes[:200] if len(v)]
    centers, axes, half = fit_obb_batch(items)
    assert centers.shape == (len(items), 3) and axes.shape == (len(items), 3, 3)
    assert half.shape == (len(items), 3)
    for i, v in enumerate(items):
        b = fit_obb(v)
        assert np.array_equal(b.center, centers[i])
        assert np.array_equal(b.axes, axes[i])
        assert np.array_equal(b.half_extents, half[i])
    c, a, h = fit_obb_batch([])
    assert c.shape == (0, 3) and a.shape == (0, 3, 3) and h.shape == (0, 3)


def test_rotated_box_is_recovered():
    rng = np.random.default_rng(1)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rot = q * np.sign(np.linalg.det(q))
    half = np.array([0.3, 2.0, 0.7])
    local = rng.uniform(-1, 1, size=(500, 3)) * half
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * half
    pts = np.concatenate([local, corners]) @ rot.T + [5.0, -1.0, 2.0]
    b = fit_obb(pts)
    assert np.allclose(b.half_extents, [2.0, 0.7, 0.3], atol=1e-9)
    assert np.allclose(b.center, [5.0, -1.0, 2.0], atol=1e-9)
    for row, k in zip(b.axes, [1, 2, 0]):
        assert abs(row @ rot[:, k]) > 1 - 1e-12
    expected = corners @ rot.T + [5.0, -1.0, 2.0]
    gap = np.linalg.norm(b.corners()[:, None] - expected[None], axis=2).min(axis=1)
    assert gap.max() < 1e-9
    assert b.contains(pts, 1e-9).all()


def test_degenerate_sets():
    b = fit_obb(np.array([[1.0, 2.0, 3.0]]))
    assert np.array_equal(b.half_extents, np.zeros(3))
    assert np.array_equal(b.axes, [[0, 1, 0], [1, 0, 0], [0, 0, -1]])
    line = np.outer(np.arange(5.0), [1.0, 2.0, -0.5])
    b = fit_obb(line)
    assert b.half_extents[1] == b.half_extents[2] == 0.0
    assert np.isclose(b.half_extents[0], 0.5 * np.linalg.norm(line[-1]))
    plane = np.array([[x, 0.25, z] for x in range(4) for z in range(3)], float)
    b = fit_obb(plane)
    assert np.array_equal(b.half_extents, [1.5, 1.0, 0.0])
    assert np.array_equal(np.abs(b.axes[2]), [0.0, 1.0, 0.0])
    for pts in (line, plane):
        _check_canonical(fit_obb(pts))


@pytest.mark.parametrize(
    ("points", "match"),
    [
        (np.zeros((0, 3)), "points: empty point set"),
        (np.zeros((4, 2)), r"points: expected shape \(N, 3\), got \(4, 2\)"),
        (np.zeros(3), r"points: expected shape \(N, 3\), got \(3,\)"),
        (np.array([[0.0, 0.0, 0.0], [1.0, np.nan, 0.0]]), "points: non-finite value at index 4"),
        (np.array([[np.inf, 0.0, 0.0]]), "points: non-finite value at index 0"),
        (np.array([[-1e308, 0.0, 0.0], [1e308, 0.0, 0.0]]), "points: coordinate range too large"),
    ],
)
def test_bad_points_raise(points, match):
    with pytest.raises(ValueError, match=match):
        fit_obb(points)


def test_bad_options_and_batches_raise():
    pts = np.random.default_rng(2).normal(size=(10, 3))
    with pytest.raises(ValueError, match="volume_tolerance"):
        fit_obb(pts, volume_tolerance=-0.1)
    with pytest.raises(ValueError, match="up: must be a non-zero vector"):
        fit_obb(pts, up=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=r"up: expected shape \(3,\)"):
        fit_obb(pts, up=(0.0, 1.0))
    with pytest.raises(ValueError, match="up: non-finite"):
        fit_obb(pts, up=(0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match=r"point_sets\[1\]: empty point set"):
        fit_obb_batch([pts, np.zeros((0, 3)), np.zeros((0, 3))])
    with pytest.raises(ValueError, match=r"point_sets\[2\]: non-finite value at index 1"):
        fit_obb_batch([pts, pts, np.array([[0.0, np.inf, 0.0]])])
    with pytest.raises(ValueError, match=r"point_sets\[0\]: expected shape \(N, 3\)"):
        fit_obb_batch([np.zeros((3, 4))])


def _round_prism(axis: np.ndarray, n: int, roll: float) -> np.ndarray:
    """A prism of length 2 along unit ``axis`` whose cross-section is a regular ``n``-gon of
    radius 0.3, turned by ``roll`` about the axis (a knob, a cap, a nail)."""
    a = axis / np.linalg.norm(axis)
    u = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    t = roll + 2 * np.pi * np.arange(n) / n
    ring = 0.3 * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)
    return np.concatenate([ring - a, ring + a])


def _quarter_turn_y(p: np.ndarray, q: int) -> np.ndarray:
    """``(N, 3)`` turned ``q`` quarter turns about y, exactly: (x, y, z) -> (z, y, -x)."""
    for _ in range(q):
        p = np.stack([p[:, 2], p[:, 1], -p[:, 0]], axis=1)
    return p


@pytest.mark.parametrize("axis", [(0.0, 1e-3, 1.0), (1.0, 1e-3, 0.0), (0.0, 1.0, 0.0)])
@pytest.mark.parametrize("n, roll", [(96, 0.3), (32, 0.77), (12, 0.1)])
def test_round_parts_get_the_turned_box_when_turned(axis, n, roll):
    """A round part's near-minimal boxes differ by a roll about its axis; the fit rolls into
    world alignment and breaks ties by it, so the box of the part turned a quarter turn about
    the vertical is the turned box (issue 36's rotation criterion), and a fine polygon's box
    is world-aligned."""
    pts = _round_prism(np.asarray(axis), n, roll)
    b0 = fit_obb(pts)
    if n >= 32:
        assert np.abs(b0.axes).max(axis=1).sum() > 3 - 1e-5, b0.axes  # up to the 1e-3 tilt
    for q in (1, 2, 3):
        b = fit_obb(_quarter_turn_y(pts, q))
        _check_canonical(b)
        turned = _quarter_turn_y(b0.axes, q)
        for k in range(3):  # every row parallel to a turned row of the same half-extent
            assert any(abs(b.half_extents[k] - b0.half_extents[m]) < 1e-9
                       and abs(turned[m] @ b.axes[k]) > 1 - 1e-9 for m in range(3)), (q, k, b.axes, turned)
