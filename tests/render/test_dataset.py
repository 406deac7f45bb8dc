"""Rendered partial scans: geometry, labels and ANCSH ground truth checked against the meshes
moved by an independent forward kinematics of mobility_v2.json; reproducibility; resume."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ._geometry import point_mesh_distance
from kinmo.data.labels import rigid_groups
from kinmo.data.readers import read_shape
from kinmo.geometry import load_obj
from kinmo.render.camera import back_project
from kinmo.render.dataset import (
    MANIFEST_COLUMNS,
    frame_images,
    RenderConfig,
    load_frame,
    read_manifest,
    render_dataset,
    render_one,
)

# refrigerator (hinge), table with a drawer (slider), bottle (cylindrical), cabinet (4 doors)
OBJECTS = ["10849", "20453", "3596", "46108"]
PARTNET = "179"  # a PartNet chair: no motion, must fail with a reason
CONFIG = RenderConfig(width=160, height=120, seed=7)
FRAMES = 2


@pytest.fixture(scope="module")
def root(tmp_path_factory, mobility_root: Path, partnet_root: Path) -> Path:
    r = tmp_path_factory.mktemp("objects")
    for oid in OBJECTS:
        (r / oid).symlink_to(mobility_root / oid, target_is_directory=True)
    (r / PARTNET).symlink_to(partnet_root / PARTNET, target_is_directory=True)
    return r


@pytest.fixture(scope="module")
def rendered(tmp_path_factory, root: Path):
    out = tmp_path_factory.mktemp("render")
    result = render_dataset(root, out, FRAMES, CONFIG, workers=1, progress=False)
    return out, result


def _forward_kinematics(mobility: list[dict], state: dict[str, list[float]]) -> dict[int, np.ndarray]:
    """Rest -> current 4x4 motion of every link, straight from mobility_v2.json."""
    by_id = {l["id"]: l for l in mobility}
    out: dict[int, np.ndarray] = {}

    def pose(lid: int) -> np.ndarray:
        if lid in out:
            return out[lid]
        lk = by_id[lid]
        parent = np.eye(4) if lk["parent"] == -1 else pose(lk["parent"])
        M = np.eye(4)
        if lk["parent"] != -1 and lk["joint"] in ("hinge", "slider"):
            o = np.asarray(lk["jointData"]["axis"]["origin"], float)
            d = np.asarray(lk["jointData"]["axis"]["direction"], float)
            d /= np.linalg.norm(d)
            t, a = state[str(lid)]
            R = Rotation.from_rotvec(a * d).as_matrix()
            M[:3, :3], M[:3, 3] = R, o - R @ o + t * d
        out[lid] = parent @ M
        return out[lid]

    for lid in by_id:
        pose(lid)
    return out


def _link_meshes(shape) -> dict[int, list[tuple[np.ndarray, np.ndarray]]]:
    return {l.id: [load_obj(shape.mesh_path(m)) for pid in l.parts for m in shape.hierarchy.mesh_names(pid)]
            for l in shape.links}


def _tris(meshes, T: np.ndarray) -> np.ndarray:
    return np.concatenate([(v @ T[:3, :3].T + T[:3, 3])[f] for v, f in meshes])


def _frames(out: Path, oid: str) -> list[dict]:
    return [load_frame(p) for p in sorted((out / oid).glob("*.npz"))]


@pytest.mark.exactdata
def test_manifest_and_failures(rendered, root: Path) -> None:
    out, result = rendered
    assert result.n_objects == len(OBJECTS) + 1
    rows = read_manifest(out)
    assert [tuple(r.as_dict()) for r in rows[:1]] == [MANIFEST_COLUMNS]
    assert len(rows) == (len(OBJECTS) + 1) * FRAMES
    ok = [r for r in rows if r.status == "ok"]
    assert sorted({r.id for r in ok}) == sorted(OBJECTS) and len(ok) == len(OBJECTS) * FRAMES
    for r in ok:
        assert (out / r.file).is_file() and r.n_points > 500 and r.error == ""
    bad = [r for r in rows if r.id == PARTNET]
    assert [r.status for r in bad] == ["failed"] * FRAMES
    assert "mobility_v2.json" in bad[0].error and str(root / PARTNET) in bad[0].error
    assert result.failed_objects == [PARTNET]
    meta = json.loads((out / "manifest.json").read_text())
    assert meta["complete"] and meta["counts"] == {"ok": len(ok), "skipped": 0, "failed": FRAMES}


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", OBJECTS)
def test_points_lie_on_their_links(rendered, mobility_root: Path, oid: str) -> None:
    out, _ = rendered
    _check_surface(mobility_root / oid, _frames(out, oid))


@pytest.mark.exactdata
@pytest.mark.parametrize("oid", OBJECTS)
def test_ancsh_ground_truth(rendered, mobility_root: Path, oid: str) -> None:
    out, _ = rendered
    _check_ground_truth(mobility_root / oid, _frames(out, oid))


def test_synthetic_cabinet_nested_joints(cabinet: Path, tmp_path: Path) -> None:
    """A knob hinged on a door hinged on the body (nested moving links), a static base, a
    non-unit axis: the same checks, through chained joints."""
    rows = render_one(cabinet, tmp_path, CONFIG, 4)
    assert [r.status for r in rows] == ["ok"] * 4, rows[0].error
    frames = _frames(tmp_path, cabinet.name)
    assert 2 in frames[0]["joint_ids"]  # the knob joint, child of the door
    _check_surface(cabinet, frames)
    _check_ground_truth(cabinet, frames)


def _check_surface(folder: Path, frames: list[dict]) -> None:
    oid = folder.name
    shape = read_shape(folder)
    mobility = json.loads((folder / "mobility_v2.json").read_text())
    meshes = _link_meshes(shape)
    allv = np.concatenate([v for ms in meshes.values() for v, _ in ms])
    diag = np.linalg.norm(allv.max(0) - allv.min(0))
    rng = np.random.default_rng(0)
    seen: set[int] = set()
    for fr in frames:
        H, W = fr["image_size"]
        assert (H, W) == (CONFIG.height, CONFIG.width)
        poses = _forward_kinematics(mobility, fr["meta"]["view"]["state"])
        c2w = fr["cam_to_world"]
        world = fr["points"].astype(np.float64) @ c2w[:3, :3].T + c2w[:3, 3]
        sel = rng.choice(len(world), min(400, len(world)), replace=False)
        everything = np.concatenate([_tris(meshes[l], poses[l]) for l in meshes])
        d_any = point_mesh_distance(world[sel], everything) / diag
        assert np.quantile(d_any, 0.99) < 0.01 and np.median(d_any) < 1e-4
        labels = fr["link"][sel]
        assert set(np.unique(fr["link"])) <= set(meshes)
        for lid in np.unique(labels):
            m = labels == lid
            d_own = point_mesh_distance(world[sel][m], _tris(meshes[int(lid)], poses[int(lid)])) / diag
            assert np.quantile(d_own, 0.99) < 0.01, (oid, lid)
        seen |= set(np.unique(fr["link"]).tolist())
    # the segmentation is not trivial: the moving and the fixed links are both seen
    assert len(seen) >= 2, seen


def _check_ground_truth(folder: Path, frames: list[dict]) -> None:
    shape = read_shape(folder)
    mobility = json.loads((folder / "mobility_v2.json").read_text())
    meshes = _link_meshes(shape)
    groups = rigid_groups(shape.links)
    allv = np.concatenate([v for ms in meshes.values() for v, _ in ms])
    lo, hi = allv.min(0), allv.max(0)
    oc, osc = (lo + hi) / 2, np.linalg.norm(hi - lo)
    boxes = {}
    for g in set(groups.values()):
        v = np.concatenate([v for l, ms in meshes.items() if groups[l] == g for v, _ in ms])
        boxes[g] = ((v.min(0) + v.max(0)) / 2, np.linalg.norm(v.max(0) - v.min(0)))
    for fr in frames:
        pts = fr["points"].astype(np.float64)
        npcs, naocs = fr["npcs"].astype(np.float64), fr["naocs"].astype(np.float64)
        assert npcs.min() >= -1e-3 and npcs.max() <= 1 + 1e-3  # NPCS in the unit cube
        assert naocs.min() >= -1e-3 and naocs.max() <= 1 + 1e-3
        poses = _forward_kinematics(mobility, fr["meta"]["view"]["state"])
        c2w = fr["cam_to_world"]
        w2c = np.linalg.inv(c2w)
        world = pts @ c2w[:3, :3].T + c2w[:3, 3]
        rest = np.empty_like(world)
        for lid in np.unique(fr["link"]):
            m = fr["link"] == lid
            Ti = np.linalg.inv(poses[int(lid)])
            rest[m] = world[m] @ Ti[:3, :3].T + Ti[:3, 3]
            assert (fr["part"][m] == groups[int(lid)]).all()
        # NAOCS: the object at rest, box centred at 0.5 with unit diagonal
        assert np.abs(naocs - ((rest - oc) / osc + 0.5)).max() < 1e-3
        # NPCS per rigid part, and the NPCS -> camera similarity of each part
        assert list(fr["part_ids"]) == sorted(boxes)
        for k, pid in enumerate(fr["part_ids"]):
            c, s = boxes[int(pid)]
            m = fr["part"] == pid
            assert fr["part_scale"][k] == pytest.approx(s, rel=1e-5)
            if not m.any():  # part not in view
                continue
            assert np.abs(npcs[m] - ((rest[m] - c) / s + 0.5)).max() < 1e-3
            R, t = fr["part_rotation"][k].astype(np.float64), fr["part_translation"][k]
            assert np.allclose(R @ R.T, np.eye(3), atol=1e-5)
            recon = fr["part_scale"][k] * npcs[m] @ R.T + t
            assert np.abs(recon - pts[m]).max() < 1e-3 * s
            b = fr["part_bounds"][k]
            assert b.min() >= -1e-5 and b.max() <= 1 + 1e-5 and np.allclose(b.mean(0), 0.5, atol=1e-5)
        # NAOCS -> camera maps the root part's points (it does not move)
        root = groups[next(l["id"] for l in mobility if l["parent"] == -1)]
        m = fr["part"] == root
        recon = fr["naocs_scale"] * naocs[m] @ fr["naocs_rotation"].T + fr["naocs_translation"]
        assert m.any() and np.abs(recon - pts[m]).max() < 1e-3 * osc
        # joints: camera frame at the rendered state, NAOCS at rest, states within limits
        moving = {l["id"]: l for l in mobility if l["joint"] in ("hinge", "slider")}
        assert sorted(fr["joint_ids"].tolist()) == sorted(moving)
        for i, lid in enumerate(fr["joint_ids"]):
            lk = moving[int(lid)]
            o = np.asarray(lk["jointData"]["axis"]["origin"], float)
            d = np.asarray(lk["jointData"]["axis"]["direction"], float)
            d /= np.linalg.norm(d)
            M = w2c @ poses[lk["parent"]]
            assert np.allclose(fr["joint_origin"][i], M[:3, :3] @ o + M[:3, 3], atol=1e-5)
            assert np.allclose(fr["joint_direction"][i], M[:3, :3] @ d, atol=1e-5)
            assert np.allclose(fr["joint_origin_naocs"][i], (o - oc) / osc + 0.5, atol=1e-5)
            assert np.allclose(fr["joint_direction_naocs"][i], d, atol=1e-6)
            assert fr["joint_parent"][i] == groups[lk["parent"]]
            t, a = fr["meta"]["view"]["state"][str(int(lid))]
            assert fr["joint_translation"][i] == pytest.approx(t, abs=1e-6)
            assert fr["joint_angle"][i] == pytest.approx(a, abs=1e-6)
            kind = ["revolute", "prismatic", "cylindrical"][fr["joint_type"][i]]
            if lk["joint"] == "hinge":
                assert kind == "revolute" and t == 0.0
                lim = fr["joint_angle_limits"][i]
                assert lim[0] - 1e-6 <= a <= lim[1] + 1e-6
            else:
                lim = sorted((lk["jointData"]["limit"]["a"], lk["jointData"]["limit"]["b"]))
                assert lim[0] - 1e-9 <= t <= lim[1] + 1e-9
                rot = lk["jointData"]["limit"].get("rotates", False)
                assert kind == ("cylindrical" if rot else "prismatic")
                assert (a != 0.0) == rot


@pytest.mark.exactdata
def test_reproducible_and_resumable(tmp_path: Path, mobility_root: Path) -> None:
    src = mobility_root / "3596"
    a, b = tmp_path / "a", tmp_path / "b"
    rows = render_one(src, a, CONFIG, 2)
    assert [r.status for r in rows] == ["ok", "ok"]
    render_one(src, b, CONFIG, 2)
    for f in ("00000.npz", "00001.npz"):
        fa, fb = load_frame(a / "3596" / f), load_frame(b / "3596" / f)
        assert fa["meta"] == fb["meta"]
        for k in fa:
            if k != "meta":
                assert np.array_equal(fa[k], fb[k]), k
    f0, f1 = load_frame(a / "3596" / "00000.npz"), load_frame(a / "3596" / "00001.npz")
    depth, labels = frame_images(f0)  # the images the frame was back-projected from
    pts, pix = back_project(depth, f0["K"], labels >= 0)
    assert np.array_equal(pix, f0["pixels"]) and np.allclose(pts, f0["points"], rtol=1e-6)
    assert np.array_equal(labels[labels >= 0], f0["link"])
    assert f0["meta"]["view"] != f1["meta"]["view"]  # frames differ from each other
    other = render_one(src, tmp_path / "c", RenderConfig(width=160, height=120, seed=8), 1)
    assert other[0].status == "ok"
    assert load_frame(tmp_path / "c" / "3596" / "00000.npz")["meta"]["view"] != f0["meta"]["view"]

    # resume: existing frames are skipped (not rewritten), new frames rendered
    stamps = {p.name: p.stat().st_mtime_ns for p in (a / "3596").glob("*.npz")}
    rows = render_one(src, a, CONFIG, 3)
    assert [r.status for r in rows] == ["skipped", "skipped", "ok"]
    assert rows[0].n_points == f0["points"].shape[0]
    assert all((a / "3596" / n).stat().st_mtime_ns == t for n, t in stamps.items())
    assert load_frame(a / "3596" / "00002.npz")["meta"]["frame"] == 2
    # a changed setting re-renders instead of mixing settings
    rows = render_one(src, a, RenderConfig(width=80, height=60, seed=7), 1)
    assert rows[0].status == "ok"
    assert tuple(load_frame(a / "3596" / "00000.npz")["image_size"]) == (60, 80)
    assert not [p for p in (a / "3596").iterdir() if p.name.endswith(".tmp")]


@pytest.mark.exactdata
def test_a_held_cylindrical_joint_keeps_its_rest_angle(tmp_path: Path, mobility_root: Path) -> None:
    """``turn_cylindrical=False`` (ANCSH's scans): the bottle's screw cap slides as before but
    never turns; the random stream, so the translations and view directions, are unchanged."""
    src = mobility_root / "3596"  # bottle: its lid is a slider that rotates
    turned = render_one(src, tmp_path / "t", CONFIG, 3)
    held_config = RenderConfig(width=160, height=120, seed=7, turn_cylindrical=False)
    held = render_one(src, tmp_path / "h", held_config, 3)
    assert [r.status for r in turned + held] == ["ok"] * 6
    for f in ("00000.npz", "00001.npz", "00002.npz"):
        ft, fh = load_frame(tmp_path / "t" / "3596" / f), load_frame(tmp_path / "h" / "3596" / f)
        assert list(fh["joint_type"]) == [2]  # still recorded as cylindrical
        (tt, at), = ft["meta"]["view"]["state"].values()
        (th, ah), = fh["meta"]["view"]["state"].values()
        assert at != 0.0 and ah == 0.0 and th == tt
        assert fh["joint_angle"][0] == 0.0
        for k in ("azimuth_deg", "elevation_deg"):  # the distance fits the posed object
            assert ft["meta"]["view"][k] == fh["meta"]["view"][k]
        # the cap's pose is its translation alone: the base's rotation, moved along the axis
        R = fh["part_rotation"]
        assert np.allclose(R[0], R[1], atol=1e-5)
        assert not np.allclose(ft["part_rotation"][0], ft["part_rotation"][1], atol=1e-3)
    # frames of the other setting are not taken as up to date
    assert render_one(src, tmp_path / "t", held_config, 1)[0].status == "ok"


@pytest.mark.exactdata
def test_cli_parallel_matches_serial(tmp_path: Path, mobility_root: Path) -> None:
    from typer.testing import CliRunner

    from kinmo.cli import app

    src = tmp_path / "objs"
    src.mkdir()
    for oid in ("10849", "20453"):
        (src / oid).symlink_to(mobility_root / oid, target_is_directory=True)
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["render", str(src), "--out", str(out), "--frames-per-object", "2",
                                   "--seed", "3", "--size", "64", "--workers", "2", "--quiet"])
    assert res.exit_code == 0, res.output
    rows = read_manifest(out)
    assert [(r.id, r.frame, r.status) for r in rows] == [
        (o, f, "ok") for o in ("10849", "20453") for f in range(2)]
    serial = render_one(src / "20453", tmp_path / "serial", RenderConfig(64, 64, seed=3), 2)
    for r in serial:
        fa = load_frame(out / r.file)
        fb = load_frame(tmp_path / "serial" / r.file)
        assert np.array_equal(fa["points"], fb["points"]) and np.array_equal(fa["npcs"], fb["npcs"])
    again = CliRunner().invoke(app, ["render", str(src), "--out", str(out), "--frames-per-object", "2",
                                     "--seed", "3", "--size", "64", "--workers", "1", "--quiet"])
    assert again.exit_code == 0 and "4 skipped" in " ".join(again.output.split()), again.output
