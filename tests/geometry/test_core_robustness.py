"""``kinmo._core`` never crashes: the findings of issue 14 and property tests of the whole API.

Each finding of the issue (huge requested sizes, huge non-contiguous views, O(N²) OBB fits,
odd OBJ files, extreme scales) is one test; the Hypothesis tests then throw random shapes,
dtypes, strides, NaN/inf, degenerate and extreme geometry and huge counts at every function
and check that the only outcomes are a result or an ``Exception`` (``ValueError``,
``OSError``, ``TypeError``, ``MemoryError``) whose message names the argument, never pyo3's
``PanicException`` (a ``BaseException``) or an aborted interpreter. Examples are few and
small so the whole file runs in seconds.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from kinmo import _core

# Hypothesis casts huge float64 draws into float32 arrays on purpose (inf values).
pytestmark = pytest.mark.filterwarnings("ignore:overflow encountered in cast:RuntimeWarning")

TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)

# A view of 2**31 rows that numpy never materialises: copying it needs 48 GiB.
HUGE_VIEW = np.broadcast_to(np.zeros(3), (2**31, 3))

# What a binding may raise on bad input; PanicException is a BaseException, not in here.
EXPECTED = (ValueError, OSError, TypeError, MemoryError, OverflowError)


def _calls_ok_or_names(fn, *names: str) -> object:
    """Call ``fn``; an exception must be an ordinary one naming one of ``names``."""
    try:
        return fn()
    except EXPECTED as e:
        # pyo3 reports a dtype mismatch in a note: "while processing 'points'".
        msg = " ".join([str(e), *getattr(e, "__notes__", [])])
        assert any(n in msg for n in names), f"{type(e).__name__}: {msg!r} names none of {names}"
        return e


# --- findings of issue 14 -----------------------------------------------------------------


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: _core.fit_obb(HUGE_VIEW), "points"),
        (lambda: _core.fit_obb_batch([TETRA_V, HUGE_VIEW]), "point_sets[1]"),
        (lambda: _core.interaction_region(HUGE_VIEW, TETRA_V, 0.1), "moving"),
        (lambda: _core.interaction_region(TETRA_V, HUGE_VIEW, 0.1), "reference"),
        (lambda: _core.sample_surface(HUGE_VIEW, TETRA_F, 10, 0), "mesh vertices"),
    ],
)
def test_huge_non_contiguous_view_is_refused_before_copying(call, name: str) -> None:
    with pytest.raises(ValueError, match=rf"^{re.escape(name)}: .*2147483648, 3.*limit"):
        call()


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: _core.sample_surface(TETRA_V, TETRA_F, 2**40, 0), "n"),
        (lambda: _core.sample_surface_groups([(TETRA_V, TETRA_F)], [[0]], 10**9, 0), "n"),
        (
            lambda: _core.apply_motions(
                np.zeros((100_000, 3)),
                np.zeros((100_000, 3)),
                np.tile([0.0, 0.0, 1.0], (100_000, 1)),
                np.zeros(100_000),
                np.zeros(100_000),
            ),
            "origins x points",
        ),
    ],
)
def test_huge_requested_sizes_are_value_errors_naming_the_argument(call, name: str) -> None:
    with pytest.raises(ValueError, match=rf"^{re.escape(name)}.*more than the limit"):
        call()


def test_fit_obb_on_sphere_points_scales_like_its_hull() -> None:
    # Every point is a hull vertex: the face-flush family used to visit every hull face
    # (32k points: 40 s). Now capped: 20k points well under the old time.
    rng = np.random.default_rng(0)
    p = rng.normal(size=(20_000, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    t = time.perf_counter()
    center, axes, half = _core.fit_obb(p)
    elapsed = time.perf_counter() - t
    assert elapsed < 10.0, elapsed
    local = (p - center) @ axes.T
    assert np.all(np.abs(local) <= half + 1e-9)
    # A sphere's tight box is a cube of side ~2.
    assert np.allclose(half, 1.0, atol=0.02)


@pytest.mark.parametrize(
    "name, text, match",
    [
        ("readme.obj", "This is a README, not a mesh.\n", r"readme\.obj: not an OBJ file"),
        ("huge.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", r"huge\.obj: .*float32"),
        ("huger.obj", "v 0 0 0\nv 1 0 0\nv 0 1e200 0\nf 1 2 3\n", r"huger\.obj: .*float32"),
        ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", r"nan\.obj: .*non-finite"),
    ],
)
def test_bad_obj_text_is_a_value_error_naming_the_file(
    tmp_path: Path, name: str, text: str, match: str
) -> None:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        _core.load_obj(str(path))


def test_obj_with_utf8_bom_loads(tmp_path: Path) -> None:
    path = tmp_path / "bom.obj"
    path.write_bytes(b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    v, f = _core.load_obj(str(path))
    assert v.shape == (3, 3) and f.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize("special", ["/dev/zero", "/dev/urandom"])
def test_non_regular_file_is_refused_not_read(special: str) -> None:
    with pytest.raises(OSError, match=rf"^{special}: cannot read: not a regular file"):
        _core.load_obj(special)


@pytest.mark.parametrize("scale", [1e200, 1e-300, 1.0])
def test_mesh_distance_is_scale_robust(scale: float) -> None:
    d = _core.mesh_distance(TETRA_V * scale, TETRA_F, (TETRA_V + [2.0, 0, 0]) * scale, TETRA_F)
    assert d == pytest.approx(scale, rel=1e-12)
    pairs, dist = _core.contact_pairs(
        [(TETRA_V * scale, TETRA_F), ((TETRA_V + [2.0, 0, 0]) * scale, TETRA_F)], 1.5 * scale
    )
    assert pairs.tolist() == [[0, 1]] and dist[0] == pytest.approx(scale, rel=1e-12)


def test_extreme_direction_is_not_zero_length() -> None:
    for d in ([1e300, 1e300, 0.0], [1e-300, 0.0, 0.0]):
        m = _core.motion_transforms(np.zeros((1, 3)), np.array([d]), np.array([0.5]), np.zeros(1))
        axis = np.array(d) / np.max(np.abs(d))
        axis /= np.linalg.norm(axis)
        # The rotation axis is fixed by the rotation.
        assert np.allclose(m[0, :3, :3] @ axis, axis)
    with pytest.raises(ValueError, match=r"directions\[0\]: zero-length"):
        _core.motion_transforms(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1), np.zeros(1))


# --- property tests -----------------------------------------------------------------------

PROPS = settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    derandomize=True,
)

special_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, 5e-324, 1.7e308]),
)
dtypes = st.sampled_from([np.float64, np.float32, np.int64, np.int32, np.bool_, np.complex128])


@st.composite
def arrays(draw, rows: int = 12, dtype=None) -> np.ndarray:
    """Arrays of random dtype, shape (mostly (N, 3)), strides and values, NaN/inf included."""
    dt = draw(dtypes) if dtype is None else dtype
    shape = draw(
        st.one_of(
            st.tuples(st.integers(0, rows), st.just(3)),
            hnp.array_shapes(min_dims=1, max_dims=3, max_side=5),
        )
    )
    elements = special_floats if np.issubdtype(dt, np.floating) else None
    a = draw(hnp.arrays(dt, shape, elements=elements))
    if a.ndim == 2 and a.shape[0] > 1 and draw(st.booleans()):
        a = np.repeat(a, 2, axis=0)[::2]  # non-contiguous view
    if a.ndim == 2 and draw(st.booleans()):
        a = np.asfortranarray(a)
    return a


@st.composite
def meshes(draw) -> tuple[np.ndarray, np.ndarray]:
    """Float64 meshes: random, degenerate (collinear, repeated vertices) or extreme scale."""
    n = draw(st.integers(0, 8))
    scale = draw(st.sampled_from([1.0, 1e-300, 1e300, 1e150]))
    v = draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-1, 1, width=32))) * scale
    if n and draw(st.booleans()):
        v[:, 2] = 0.0  # coplanar
    m = draw(st.integers(0, 6))
    f = draw(hnp.arrays(np.int64, (m, 3), elements=st.integers(-1, max(n, 1))))
    return v, f


counts = st.one_of(st.integers(-3, 50), st.sampled_from([2**31, 2**40, 2**63, 2**64, 10**30]))


@PROPS
@given(points=arrays(), up=st.one_of(st.none(), st.tuples(special_floats, special_floats, special_floats)))
def test_fit_obb_never_panics(points: np.ndarray, up) -> None:
    r = _calls_ok_or_names(lambda: _core.fit_obb(points, up=up), "points", "up", "float64")
    if not isinstance(r, Exception):
        center, axes, half = r
        assert np.all(np.isfinite(center)) and np.allclose(axes @ axes.T, np.eye(3), atol=1e-9)
        assert np.all(half >= 0)


@PROPS
@given(sets=st.lists(arrays(rows=6), max_size=3))
def test_fit_obb_batch_never_panics(sets: list[np.ndarray]) -> None:
    _calls_ok_or_names(lambda: _core.fit_obb_batch(sets), "point_sets")


@PROPS
@given(mesh=meshes(), n=counts, seed=st.integers(-2, 2**65))
def test_sample_surface_never_panics(mesh, n: int, seed: int) -> None:
    v, f = mesh
    r = _calls_ok_or_names(
        lambda: _core.sample_surface(v, f, n, seed), "mesh", "n", "seed", "area", "faces"
    )
    if not isinstance(r, Exception):
        p, face = r
        assert p.shape == (n, 3) and face.shape == (n,) and np.all(np.isfinite(p))


@PROPS
@given(ms=st.lists(meshes(), max_size=3), groups=st.lists(st.lists(st.integers(-1, 3), max_size=3), max_size=3), n=counts)
def test_sample_surface_groups_never_panics(ms, groups, n: int) -> None:
    _calls_ok_or_names(
        lambda: _core.sample_surface_groups(ms, groups, n, 0), "meshes", "groups", "n"
    )


@PROPS
@given(ms=st.lists(meshes(), max_size=4), tol=special_floats)
def test_contact_pairs_never_panics(ms, tol: float) -> None:
    r = _calls_ok_or_names(lambda: _core.contact_pairs(ms, tol), "meshes", "tolerance")
    if not isinstance(r, Exception):
        pairs, dist = r
        assert np.all(pairs[:, 0] < pairs[:, 1]) and np.all((dist >= 0) & (dist <= tol))


@PROPS
@given(a=meshes(), b=meshes())
def test_mesh_distance_never_panics(a, b) -> None:
    r = _calls_ok_or_names(lambda: _core.mesh_distance(*a, *b), "mesh_a", "mesh_b", "meshes")
    if not isinstance(r, Exception):
        assert r >= 0 and np.isfinite(r)


@PROPS
@given(a=arrays(), b=arrays(), radius=special_floats)
def test_interaction_region_never_panics(a: np.ndarray, b: np.ndarray, radius: float) -> None:
    _calls_ok_or_names(
        lambda: _core.interaction_region(a, b, radius), "moving", "reference", "radius"
    )


@PROPS
@given(
    points=arrays(rows=6),
    o=arrays(rows=4, dtype=np.float64),
    d=arrays(rows=4, dtype=np.float64),
    ang=hnp.arrays(np.float64, st.integers(0, 5), elements=special_floats),
    tr=hnp.arrays(np.float64, st.integers(0, 5), elements=special_floats),
)
def test_motions_never_panic(points, o, d, ang, tr) -> None:
    names = ("points", "origins", "directions", "angles", "translations")
    r = _calls_ok_or_names(lambda: _core.motion_transforms(o, d, ang, tr), *names)
    if not isinstance(r, Exception):
        assert r.shape == (len(o), 4, 4)
    _calls_ok_or_names(lambda: _core.apply_motions(points, o, d, ang, tr), *names)


@settings(max_examples=20, deadline=None, derandomize=True)
@given(content=st.binary(max_size=200) | st.text(max_size=200).map(str.encode))
def test_load_obj_never_panics(tmp_path_factory, content: bytes) -> None:
    path = tmp_path_factory.mktemp("obj") / "random.obj"
    path.write_bytes(content)
    r = _calls_ok_or_names(lambda: _core.load_obj(str(path)), "random.obj")
    if not isinstance(r, Exception):
        v, f = r
        assert v.dtype == np.float64 and np.all(np.abs(v) <= np.finfo(np.float32).max)
        assert f.size == 0 or (f.min() >= 0 and f.max() < len(v))
