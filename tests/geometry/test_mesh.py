"""OBJ loading (:mod:`kinmo.geometry.mesh`, Rust ``tobj``) against trimesh and bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from trimesh.exchange.obj import load_obj as trimesh_parse_obj

from kinmo.geometry import load_obj, load_objs


def _areas(v: np.ndarray, f: np.ndarray) -> float:
    if len(f) == 0:
        return 0.0
    t = v[f]
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


@pytest.fixture(scope="module")
def all_objs(mobility_root: Path, partnet_root: Path, data_facts: dict[str, int]) -> list[Path]:
    mob = sorted(mobility_root.glob("*/textured_objs/*.obj"))
    pn = sorted(partnet_root.glob("*/objs/*.obj"))
    # Every object of both datasets has meshes.
    assert len({p.parents[1] for p in mob}) == data_facts["mobility_objects"]
    assert len({p.parents[1] for p in pn}) == data_facts["partnet_shapes"]
    return mob + pn


@pytest.fixture(scope="module")
def all_meshes(all_objs: list[Path]) -> list[tuple[np.ndarray, np.ndarray]]:
    return load_objs(all_objs)


def test_every_shared_obj_loads_and_matches_trimesh(all_objs, all_meshes):
    """All ~7.7k OBJ files: area (1e-6 relative) and bounds equal trimesh's OBJ parser.

    trimesh's parser is called directly with ``skip_materials=True`` (same geometry as
    ``trimesh.load(path, force='mesh', process=False)``, half the time: no texture lookups);
    ``test_matches_trimesh_load_exactly`` covers ``trimesh.load`` itself.
    """
    assert len(all_meshes) == len(all_objs)
    mismatches = []
    for path, (v, f) in zip(all_objs, all_meshes):
        assert v.dtype == np.float64 and f.dtype == np.int64
        assert v.ndim == 2 and v.shape[1] == 3 and f.ndim == 2 and f.shape[1] == 3
        assert len(f) > 0, path
        assert f.min() >= 0 and f.max() < len(v), path
        with open(path, "rb") as fh:
            geoms = list(trimesh_parse_obj(fh, skip_materials=True)["geometry"].values())
        ref_area = sum(_areas(np.asarray(g["vertices"]), np.asarray(g["faces"])) for g in geoms)
        ref_lo = np.min([np.asarray(g["vertices"]).min(0) for g in geoms], axis=0)
        ref_hi = np.max([np.asarray(g["vertices"]).max(0) for g in geoms], axis=0)
        area = _areas(v, f)
        if not (
            abs(area - ref_area) <= 1e-6 * ref_area
            and np.array_equal(v.min(0), ref_lo)
            and np.array_equal(v.max(0), ref_hi)
        ):
            mismatches.append((str(path), area, ref_area))
    assert not mismatches, mismatches[:5]


def test_matches_trimesh_load_exactly(all_objs, all_meshes):
    # Every 200th file through the full trimesh.load path (materials, textures, groups).
    for path, (v, f) in list(zip(all_objs, all_meshes))[::200]:
        m = trimesh.load(path, force="mesh", process=False)
        assert abs(_areas(v, f) - m.area) <= 1e-6 * m.area, path
        np.testing.assert_array_equal(np.stack([v.min(0), v.max(0)]), m.bounds)


def test_load_obj_equals_load_objs_and_accepts_pathlike(all_objs, all_meshes):
    v, f = load_obj(all_objs[0])
    np.testing.assert_array_equal(v, all_meshes[0][0])
    np.testing.assert_array_equal(f, all_meshes[0][1])
    v2, _ = load_obj(str(all_objs[0]))
    np.testing.assert_array_equal(v, v2)


def _write(tmp_path: Path, name: str, text: str | bytes) -> Path:
    p = tmp_path / name
    if isinstance(text, str):
        p.write_text(text)
    else:
        p.write_bytes(text)
    return p


def test_polygons_triangulated_objects_merged_missing_mtl_ignored(tmp_path):
    p = _write(
        tmp_path,
        "two.obj",
        "mtllib nowhere.mtl\no a\nusemtl gone\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "vt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1 4/1/1\n"
        "g b\nv 0 0 2\nv 2 0 2\nv 0 2 2\nf -3 -2 -1\n",
    )
    v, f = load_obj(p)
    assert f.shape == (3, 3) and v.shape == (7, 3)
    assert _areas(v, f) == pytest.approx(3.0, rel=1e-15)
    # The second group's triangle indexes its own (merged, offset) vertices at z = 2.
    np.testing.assert_array_equal(v[f[2]][:, 2], [2.0, 2.0, 2.0])


def test_broken_mtl_ignored(tmp_path):
    _write(tmp_path, "broken.mtl", "newmtl x\nKd not numbers\n")
    text = "mtllib broken.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    p = _write(tmp_path, "m.obj", text)
    v, f = load_obj(p)
    assert f.tolist() == [[0, 1, 2]]


def test_empty_obj_is_an_empty_mesh(tmp_path):
    v, f = load_obj(_write(tmp_path, "empty.obj", "# nothing\n"))
    assert v.shape == (0, 3) and f.shape == (0, 3)
    assert v.dtype == np.float64 and f.dtype == np.int64


def test_missing_file_is_oserror_naming_it(tmp_path):
    missing = tmp_path / "nope.obj"
    with pytest.raises(OSError, match="nope.obj"):
        load_obj(missing)
    with pytest.raises(OSError, match="is a directory|Is a directory"):
        load_obj(tmp_path)


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("v 0 zero 0\nf 1 1 1\n", "vertex position"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 2 3\n", "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x 3\n", "face"),
        ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite"),
        ("v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n", "non-finite"),
        (b"v 0 0 0\n\x00\x01\x02\x03", "binary"),
    ],
)
def test_malformed_obj_is_valueerror_naming_file_and_problem(tmp_path, text, problem):
    p = _write(tmp_path, "bad.obj", text)
    with pytest.raises(ValueError, match=problem) as e:
        load_obj(p)
    assert "bad.obj" in str(e.value)


def test_latin1_text_loads(tmp_path):
    text = b"# caf\xe9\no chaise_\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    p = _write(tmp_path, "l1.obj", text)
    assert load_obj(p)[1].shape == (1, 3)


def test_load_objs_order_and_first_error(tmp_path):
    a = _write(tmp_path, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    b = _write(tmp_path, "b.obj", "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 2 2 0\nf 1 2 3\nf 2 4 3\n")
    out = load_objs([a, b, a])
    assert [len(f) for _, f in out] == [1, 2, 1]
    assert load_objs([]) == []
    bad = _write(tmp_path, "c.obj", "v 0 0 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="c.obj"):
        load_objs([a, bad, tmp_path / "missing.obj"])
    with pytest.raises(OSError, match="missing.obj"):
        load_objs([a, tmp_path / "missing.obj", bad])
