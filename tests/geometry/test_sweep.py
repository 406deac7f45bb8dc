"""Swept-collision feasibility and line-to-mesh distance (:mod:`kinmo.geometry.sweep`, Rust).

Synthetic boxes with known answers (a door on a body, a drawer in a carcass, a rotation
about a centre axis, contact at rest), input errors, and real PartNet-Mobility doors: the
true axis with its true limit is free, the same rotation about the door's opposite edge is
not.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from kinmo import _core
from kinmo.data.labels import rigid_groups
from kinmo.data.readers import read_shape
from kinmo.geometry import load_objs, sample_surface
from kinmo.geometry.sweep import (
    DEFAULT_RELATIVE_SKIN,
    PRISMATIC,
    REVOLUTE,
    SweepObstacle,
    _f64,
    _skin_with_box,
    default_skin,
    line_mesh_distance,
    sweep_collisions,
)


def _box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(bounds=np.stack([lo, hi]))


def _concat(*boxes: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.util.concatenate(list(boxes))
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def _points(mesh: trimesh.Trimesh, n: int = 600, seed: int = 0) -> np.ndarray:
    pts, _ = sample_surface(np.asarray(mesh.vertices), np.asarray(mesh.faces), n, seed=seed)
    return pts


def _door_and_body():
    door = _points(_box([0, 0, 0], [1, 1, 0.02]))
    return door, _concat(_box([0, 0, -0.5], [1, 1, 0]))


def test_door_hinge_side_free_opposite_edge_collides_early():
    door, (v, f) = _door_and_body()
    # About -y a positive angle swings the door out of the body (+z).
    origins = np.array([[0.0, 0.0, 0.02], [1.0, 0.0, 0.02]])
    dirs = np.array([[0.0, -1.0, 0.0], [0.0, -1.0, 0.0]])
    free, coll = sweep_collisions(
        door, v, f, origins, dirs, np.array([REVOLUTE] * 2), np.full(2, np.pi / 2)
    )
    assert free.shape == coll.shape == (2, 2) and free.dtype == np.float64
    assert free[0, 0] == 1.0 and coll[0, 0] == 0.0  # the door's contact does not count
    assert free[0, 1] < 0.1 and coll[0, 1] > 0.3  # the wrong sign: into the body
    assert free[1, 0] < 0.1 and coll[1, 0] > 0.3  # the opposite edge, same sign
    assert free[1, 1] == 1.0 and coll[1, 1] == 0.0


@pytest.mark.parametrize("grow", [0.0, 0.001])
def test_drawer_slides_out_and_collides_inwards(grow):
    t = 0.05
    frame = _concat(
        _box([-t, -t, -0.45 - t], [1 + t, 0, 0]),
        _box([-t, 1, -0.45 - t], [1 + t, 1 + t, 0]),
        _box([-t, 0, -0.45 - t], [0, 1, 0]),
        _box([1, 0, -0.45 - t], [1 + t, 1, 0]),
        _box([0, 0, -0.45 - t], [1, 1, -0.45]),
    )
    # Touching (grow 0) or slightly interpenetrating (grow 0.001 < skin) the carcass.
    drawer = _points(_box([-grow, -grow, -0.4], [1 + grow, 1 + grow, 0]), 1000)
    free, coll = sweep_collisions(
        drawer, *frame, [[0, 0, 0]], [[0, 0, 1]], [PRISMATIC], [0.4], skin=0.005
    )
    assert free[0, 0] == 1.0 and coll[0, 0] == 0.0
    # Inwards, the back (z = -0.4) meets the back panel (z = -0.45): 0.05 of 0.4.
    assert free[0, 1] == pytest.approx(0.125, abs=1e-9)
    assert coll[0, 1] > 0.1


def test_door_sunk_into_the_body_opens_freely_only_with_skip_inside():
    # A door whose frame is modelled 0.03 into the body (interpenetrating, as many PartNet
    # doors are): its sunk points start inside the body; counting their exits would block
    # every motion at once.
    door = _points(_box([0.1, 0.1, -0.03], [0.9, 0.9, 0.02]))
    v, f = _concat(_box([0, 0, -0.5], [1, 1, 0]))
    inside = (door[:, 2] < -0.005) & (np.abs(door[:, :2] - 0.5).max(axis=1) < 0.4 - 0.005)
    assert inside.mean() > 0.05
    # Pulling the door straight out (+z) is free of the body; pushing it in is not.
    args = (door, v, f, [[0, 0, 0]], [[0, 0, 1]], [PRISMATIC], [0.2])
    free, coll = sweep_collisions(*args)
    assert free[0, 0] == 1.0 and coll[0, 0] == 0.0
    assert free[0, 1] < 0.2 and coll[0, 1] > 0.1
    free_all, coll_all = sweep_collisions(*args, skip_inside=False)
    assert free_all[0, 0] < 0.2 and coll_all[0, 0] >= inside.mean() - 0.02


def test_rotation_about_a_centre_axis_collides_with_the_body():
    # A door on the body's front, turned about its vertical centre line: whichever the
    # sign, one half swings into the body at once.
    door, (v, f) = _door_and_body()
    free, coll = sweep_collisions(
        door, v, f, [[0.5, 0, 0.01]], [[0, 1, 0]], [REVOLUTE], [np.pi / 2]
    )
    # The swinging half's back face is in contact at rest (not counted); its front and
    # edges are.
    assert (free < 0.05).all() and (coll > 0.15).all()


def test_first_hit_is_the_motion_parameter_and_contact_is_not_counted():
    floor = _concat(_box([-1, -1, -1], [2, 0, 2]))
    plate = _box([0, 0, 0], [1, 0.1, 1])
    pts = np.asarray(plate.vertices, float)  # 4 corners on the floor, 4 at y = 0.1
    free, coll = sweep_collisions(
        pts, *floor, [[0, 0, 0]], [[0, 1, 0]], [PRISMATIC], [0.5], hit_tolerance=0.0
    )
    assert free[0, 0] == 1.0 and coll[0, 0] == 0.0
    # Down: the 4 top corners hit at 0.1 / 0.5; the 4 resting on the floor do not count.
    assert free[0, 1] == pytest.approx(0.2, abs=1e-12)
    assert coll[0, 1] == 0.5
    # Without a skin the resting corners hit at once.
    free0, coll0 = sweep_collisions(
        pts, *floor, [[0, 0, 0]], [[0, 1, 0]], [PRISMATIC], [0.5], skin=0.0, hit_tolerance=0.0
    )
    assert coll0[0, 1] >= 0.5


def test_empty_obstacle_is_free():
    pts = np.random.default_rng(0).normal(size=(50, 3))
    free, coll = sweep_collisions(
        pts, np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((3, 3)), np.eye(3),
        [0, 1, 0], [1.0, 2.0, 0.0],
    )
    np.testing.assert_array_equal(free, np.ones((3, 2)))
    np.testing.assert_array_equal(coll, np.zeros((3, 2)))


def test_reversed_direction_swaps_the_signs():
    door, (v, f) = _door_and_body()
    rng = np.random.default_rng(3)
    o = rng.uniform(-0.5, 1.5, size=(12, 3))
    d = rng.normal(size=(12, 3))
    k = np.tile([REVOLUTE, PRISMATIC], 6)
    r = np.where(k == REVOLUTE, 1.5, 0.6)
    free, coll = sweep_collisions(door, v, f, o, d, k, r)
    free_r, coll_r = sweep_collisions(door, v, f, o, -d, k, r)
    np.testing.assert_allclose(free, free_r[:, ::-1], atol=1e-9)
    np.testing.assert_allclose(coll, coll_r[:, ::-1], atol=1e-12)
    assert ((0 <= free) & (free <= 1) & (0 <= coll) & (coll <= 1)).all()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"moving_points": np.zeros((0, 3))}, "moving_points"),
        ({"moving_points": np.full((2, 3), np.nan)}, "moving_points"),
        ({"origins": np.zeros((0, 3)), "directions": np.zeros((0, 3)), "kinds": [],
          "ranges": []}, "C = 0"),
        ({"directions": [[0.0, 0.0, 0.0]]}, "directions[0]"),
        ({"directions": [[1.0, 0.0]]}, "directions"),
        ({"kinds": [2]}, "kinds[0]"),
        ({"kinds": [0, 1]}, "kinds"),
        ({"ranges": [-1.0]}, "ranges[0]"),
        ({"ranges": [7.0]}, "2 pi"),
        ({"ranges": [np.inf]}, "ranges"),
        ({"obstacle_faces": np.array([[0, 1, 99]])}, "obstacle faces"),
        ({"n_steps": 0}, "n_steps"),
        ({"n_steps": 10**9}, "n_steps"),
        ({"skin": -1.0}, "skin"),
        ({"hit_tolerance": 1.0}, "hit_tolerance"),
        ({"moving_points": np.full((2, 3), 1e13)}, "exceeds"),
        ({"ranges": [1e13], "kinds": [PRISMATIC]}, "prismatic range"),
    ],
)
def test_bad_input_is_a_value_error_naming_the_argument(kwargs, message):
    v, f = _concat(_box([0, 0, 0], [1, 1, 1]))
    args = {
        "moving_points": np.zeros((4, 3)),
        "obstacle_vertices": v,
        "obstacle_faces": f,
        "origins": np.zeros((1, 3)),
        "directions": np.array([[0.0, 1.0, 0.0]]),
        "kinds": [REVOLUTE],
        "ranges": [1.0],
    } | kwargs
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        sweep_collisions(**args)


def test_core_binding_defaults_and_dtypes():
    door, (v, f) = _door_and_body()
    free, coll = _core.sweep_collisions(
        door, v, f, np.zeros((1, 3)), np.array([[0.0, -1.0, 0.0]]),
        np.array([0], np.int64), np.array([np.pi / 2]),
    )
    assert free.shape == (1, 2) and coll.dtype == np.float64
    assert free[0, 0] == 1.0


def test_a_prepared_obstacle_gives_the_results_of_sweep_collisions_call_after_call():
    """:class:`SweepObstacle` builds the BVH once; every later sweep against it (other
    points, other candidates, a given skin or the default one; the same points again, whose
    rest states it reuses) equals the one-shot call of the binding
    (``_core.sweep_collisions``), as does :func:`sweep_collisions`."""
    door, (v, f) = _door_and_body()
    rng = np.random.default_rng(5)
    obstacle = SweepObstacle(v, f)
    assert obstacle.n_faces == len(f)
    hit = 0.0
    for trial in range(4):
        pts = door[rng.choice(len(door), 200 + 50 * trial, replace=False)]
        o = rng.uniform(-0.5, 1.5, size=(8, 3))
        d = rng.normal(size=(8, 3))
        k = np.tile([REVOLUTE, PRISMATIC], 4)
        r = np.where(k == REVOLUTE, 1.5, 0.6)
        skin = None if trial % 2 == 0 else 0.01
        # the reference: the binding's one-shot path, which builds its own BVH
        s = default_skin(pts, v) if skin is None else skin
        want = _core.sweep_collisions(pts, v, f.astype(np.int64), o, d, k.astype(np.int64), r,
                                      n_steps=12, skin=s)
        one_shot = sweep_collisions(pts, v, f, o, d, k, r, n_steps=12, skin=skin)
        np.testing.assert_array_equal(one_shot[0], want[0])
        got = obstacle.sweep(pts, o, d, k, r, n_steps=12, skin=skin)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        # the same points again, other candidates: the obstacle reuses their rest states
        for part in (slice(0, 3), slice(3, 8)):
            again = obstacle.sweep(pts, o[part], d[part], k[part], r[part], n_steps=12, skin=skin)
            np.testing.assert_array_equal(again[0], want[0][part])
            np.testing.assert_array_equal(again[1], want[1][part])
        # ... but not under another skin (the contact rule depends on it)
        other = (default_skin(pts, v) if skin is not None else 0.01) * 3.0
        want_other = _core.sweep_collisions(pts, v, f.astype(np.int64), o, d, k.astype(np.int64),
                                            r, n_steps=12, skin=other)
        got_other = obstacle.sweep(pts, o, d, k, r, n_steps=12, skin=other)
        np.testing.assert_array_equal(got_other[0], want_other[0])
        np.testing.assert_array_equal(got_other[1], want_other[1])
        hit = max(hit, float(want[1].max()))
    assert hit > 0.1  # some candidates run into the body: a comparison that can fail
    empty = SweepObstacle(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    free, coll = empty.sweep(door, np.zeros((1, 3)), np.eye(3)[:1], [0], [1.0])
    assert empty.n_faces == 0 and free.tolist() == [[1.0, 1.0]] and coll.tolist() == [[0.0, 0.0]]
    with pytest.raises(ValueError, match="obstacle faces"):
        SweepObstacle(v, np.array([[0, 1, 99]]))
    with pytest.raises(ValueError, match=r"kinds\[0\]"):
        obstacle.sweep(door, np.zeros((1, 3)), np.eye(3)[:1], [7], [1.0])


def test_line_mesh_distance_matches_dense_samples_of_the_line():
    v, f = _concat(_box([0, 0, 0], [1, 1, 1]))
    rng = np.random.default_rng(0)
    o = rng.uniform(-2, 3, size=(40, 3))
    d = rng.normal(size=(40, 3))
    got = line_mesh_distance(o, d, v, f)
    assert got.shape == (40,) and got.dtype == np.float64
    # Reference: the line sampled densely over +-10, distance of each sample to the solid
    # unit box (numpy clip; 0 inside, where the line crosses the surface).
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    line = o[:, None] + np.linspace(-10, 10, 20001)[None, :, None] * u[:, None]
    want = np.linalg.norm(line - np.clip(line, 0, 1), axis=2).min(axis=1)
    np.testing.assert_allclose(got, want, atol=2e-3)
    assert (got <= want + 1e-9).all()
    assert (got[want == 0] == 0).all()
    with pytest.raises(ValueError, match="no faces"):
        line_mesh_distance(o, d, np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    with pytest.raises(ValueError, match=r"directions\[0\]"):
        line_mesh_distance(o[:1], np.zeros((1, 3)), v, f)


def _link_mesh(shape, link_ids) -> tuple[np.ndarray, np.ndarray]:
    names = sorted(
        {
            n
            for lk in shape.links
            if lk.id in link_ids
            for p in lk.parts
            for n in shape.hierarchy.mesh_names(p)
        }
    )
    meshes = load_objs([str(shape.mesh_dir / f"{n}.obj") for n in names])
    offsets = np.cumsum([0] + [len(m[0]) for m in meshes[:-1]])
    v = np.concatenate([m[0] for m in meshes])
    f = np.concatenate([m[1] + o for m, o in zip(meshes, offsets)])
    return v, f


@pytest.mark.exactdata
@pytest.mark.parametrize(("shape_id", "link_id"), [("12252", 0), ("45463", 0)])
def test_real_door_true_axis_free_opposite_edge_blocked(mobility_root: Path, shape_id, link_id):
    shape = read_shape(mobility_root / shape_id)
    groups = rigid_groups(shape.links)
    link = next(lk for lk in shape.links if lk.id == link_id)
    j = link.joint
    assert j.type.value == "hinge" and j.limit is not None
    moving = {lk.id for lk in shape.links if groups[lk.id] == groups[link_id]}
    mv, mf = _link_mesh(shape, moving)
    ov, of = _link_mesh(shape, {lk.id for lk in shape.links} - moving)
    pts, _ = sample_surface(mv, mf, 512, seed=0)
    lo, hi = j.limit
    sign = 0 if abs(hi) >= abs(lo) else 1  # column of the opening sign
    opening = np.deg2rad(max(abs(lo), abs(hi)))
    u = j.direction / np.linalg.norm(j.direction)
    r = pts.mean(0) - j.origin
    opposite = j.origin + 2 * (r - u * (r @ u))  # the hinge mirrored through the door
    free, coll = sweep_collisions(
        pts, ov, of, [j.origin, opposite], [u, u], [REVOLUTE] * 2, [opening] * 2
    )
    assert free[0, sign] >= 0.9 and coll[0, sign] <= 0.05, (free, coll)
    assert free[1, sign] <= 0.1 and coll[1, sign] >= 0.1, (free, coll)
    # Attachment: the true hinge lies on (within 1 % of the diagonal of) the body.
    diag = np.linalg.norm(ov.max(0) - ov.min(0))
    dist = line_mesh_distance([j.origin], [u], ov, of)
    assert dist[0] <= 0.01 * diag


def _skin_by_definition(points, vertices) -> float:
    """The default skin as first written: ``DEFAULT_RELATIVE_SKIN`` times the diagonal of the
    box of all points and vertices together (0 for none, or for a non-finite one)."""
    allp = np.concatenate([np.asarray(a, float).reshape(-1, 3) for a in (points, vertices)])
    if len(allp) == 0 or not np.isfinite(allp).all():
        return 0.0
    return float(DEFAULT_RELATIVE_SKIN * np.linalg.norm(allp.max(0) - allp.min(0)))


def test_an_obstacles_default_skin_is_default_skin_of_points_and_vertices():
    # the obstacle keeps its vertices' box; the skin it derives from it is the function's,
    # bit for bit, for points inside, outside or across that box, and 0 for a NaN point
    rng = np.random.default_rng(0)
    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    obstacle = SweepObstacle(box.vertices, box.faces)

    def skin(obs, pts):  # what obs.sweep uses without a skin
        return _skin_with_box(_f64(pts), obs._box)

    for scale, shift in [(0.1, 0.0), (3.0, 0.0), (0.5, 2.0), (1e-3, -5.0)]:
        pts = rng.normal(size=(37, 3)) * scale + shift
        assert skin(obstacle, pts) == default_skin(pts, box.vertices) == _skin_by_definition(pts, box.vertices)
    none = np.zeros((0, 3))
    assert skin(obstacle, none) == default_skin(none, box.vertices) == _skin_by_definition(none, box.vertices) > 0.0
    bad = np.array([[0.0, np.nan, 0.0]])
    assert skin(obstacle, bad) == default_skin(bad, box.vertices) == 0.0
    assert default_skin(box.vertices, bad) == default_skin(none, none) == 0.0
    empty = SweepObstacle(none, np.zeros((0, 3), np.int64))
    pts = rng.normal(size=(5, 3))
    assert skin(empty, pts) == default_skin(pts, none) == _skin_by_definition(pts, none)
