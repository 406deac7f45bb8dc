"""ANCSH samples from real rendered scans: part mapping reconciled with the renderer's rigid
parts, target consistency, normalisation, rejection of objects of another structure, category
names."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import torch

from kinmo.ancsh.config import preset
from kinmo.ancsh.dataset import (
    ANCSHFrames,
    frame_sample,
    link_centroids,
    load_samples,
    normalize_points,
    object_parts_of,
    resolve_category,
    scan_category,
    subsample_indices,
)
from kinmo.ancsh.evaluate import frame_truth
from kinmo.ancsh.scans import render_objects
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.render.dataset import load_frame

LAPTOP = "10306"
CABINET = "45463"  # StorageFurniture with two doors (0<R-1,0<R-2)
CONFIG = preset("quick", image_size=96, render_workers=1, seed=3)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory, mobility_root: Path):
    tmp = tmp_path_factory.mktemp("ancsh_ds")
    folders = {LAPTOP: mobility_root / LAPTOP, CABINET: mobility_root / CABINET}
    files, failed = render_objects(folders, tmp / "objects", tmp / "scans", 2, CONFIG, progress=False)
    assert not failed and len(files) == 4
    return {f.parent.name: sorted(p for p in files if p.parent.name == f.parent.name) for f in files}


@pytest.fixture(scope="module")
def laptops(mobility_root: Path):
    return scan_category(mobility_root, "laptop")


def test_category_names_match_any_spelling():
    cats = ["Laptop", "StorageFurniture", "Refrigerator"]
    assert resolve_category("storage_furniture", cats) == "StorageFurniture"
    assert resolve_category("Storage-Furniture", cats) == "StorageFurniture"
    assert resolve_category("LAPTOP", cats) == "Laptop"
    assert resolve_category("refrigerator", cats) == "Refrigerator"
    with pytest.raises(KinmoError, match="known: Laptop, Refrigerator, StorageFurniture"):
        resolve_category("toaster", cats)


@pytest.mark.exactdata
def test_scan_category_finds_the_structure_and_the_misfits(laptops, mobility_root):
    assert laptops.category == "Laptop"
    assert laptops.structure.signature() == "0<R-1"
    assert LAPTOP in laptops.fitting and len(laptops.fitting) >= 4
    misfits = [i for i in laptops.folders if i not in laptops.fitting]
    assert misfits and all("fits" not in laptops.describe(i) for i in misfits)
    with pytest.raises(KinmoError, match="no PartNet-Mobility object of category"):
        scan_category(mobility_root, "spaceship")


@pytest.mark.exactdata
def test_samples_are_consistent_with_the_rendered_ground_truth(rendered, laptops):
    st = laptops.structure
    parts = laptops.parts[LAPTOP]
    for f in rendered[LAPTOP]:
        fr = load_frame(f)
        s = frame_sample(fr, parts, st, theta=0.2, cache_points=1500, seed=0, path=f)
        n = len(s)
        assert n == min(1500, len(fr["points"]))
        assert s.points.shape == (n, 3) and s.npcs.shape == (n, 3) and s.naocs.shape == (n, 3)
        assert set(np.unique(s.seg)) <= {0, 1}
        assert s.npcs.min() >= -1e-3 and s.npcs.max() <= 1 + 1e-3
        # the ANCSH part of every point maps its NPCS onto it through the frame's part pose
        truth = frame_truth(fr, parts)
        for k, p in enumerate(truth.parts):
            m = s.seg == k
            if m.sum():
                fit = p.scale * s.npcs[m] @ p.rotation.T + p.translation
                assert np.abs(fit - s.points[m]).max() < 2e-3 * p.scale
        # joint targets: revolute association within theta of the NAOCS hinge, unit vectors to it
        o = np.asarray(fr["joint_origin_naocs"][0], float)
        d = np.asarray(fr["joint_direction_naocs"][0], float)
        d /= np.linalg.norm(d)
        assoc = s.joint == 1
        assert assoc.any() and np.array_equal(assoc, s.position_mask)
        rel = s.naocs[assoc] - o
        dist = np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)
        assert dist.max() < 0.2 + 1e-4
        np.testing.assert_allclose(s.heatmap[assoc], 1 - dist / 0.2, atol=1e-4)
        foot = s.naocs[assoc] + s.unitvec[assoc] * dist[:, None]
        frel = foot - o
        assert np.linalg.norm(frel - np.outer(frel @ d, d), axis=1).max() < 1e-3
        assert np.allclose(np.abs(s.axis[assoc] @ d), 1, atol=1e-5)
        assert (s.heatmap[~assoc] == 0).all() and (s.joint[~assoc] == 0).all()


@pytest.mark.exactdata
def test_items_are_normalised_fixed_size_and_reproducible(rendered, laptops):
    samples, skipped = load_samples(rendered[LAPTOP], {LAPTOP: laptops.parts[LAPTOP]}, laptops.structure,
                                    cache_points=800)
    assert len(samples) == 2 and not skipped
    ds = ANCSHFrames(samples, n_points=300, seed=1)
    a, b = ds[0], ds[0]
    assert a["xyz"].shape == (300, 3) and a["seg"].shape == (300,) and a["npcs"].shape == (300, 3)
    assert a["joint"].dtype == torch.int64 and a["seg"].dtype == torch.int64
    assert a["position_mask"].dtype == torch.bool and a["xyz"].dtype == torch.float32
    for k in a:
        assert (a[k] == b[k]).all()  # same epoch: same draw
    xyz = a["xyz"].numpy()
    assert np.abs(xyz.mean(0)).max() < 1e-4
    assert abs(np.linalg.norm(xyz, axis=1).max() - 1.0) < 1e-4
    np.testing.assert_allclose(xyz * a["scale"].item() + a["center"].numpy(), a["points"].numpy(), atol=1e-4)
    ds.set_epoch(1)
    assert not (ds[0]["points"] == a["points"]).all()
    # padding: more points asked than cached
    big = ANCSHFrames(samples, n_points=1000)[1]
    assert big["xyz"].shape == (1000, 3)
    idx = subsample_indices(5, 8, np.random.default_rng(0))
    assert sorted(set(idx.tolist())) == [0, 1, 2, 3, 4]
    xyz, c, s = normalize_points(np.array([[1.0, 1, 1], [3, 1, 1]]))
    np.testing.assert_allclose(c, [2, 1, 1])
    np.testing.assert_allclose(xyz, [[-1, 0, 0], [1, 0, 0]])
    assert s == 1.0


@pytest.mark.exactdata
def test_frames_of_another_structure_are_rejected(rendered, laptops, mobility_root):
    # the structures are read from the data (StorageFurniture's most common one changes as
    # the shared data grows)
    cab = scan_category(mobility_root, "StorageFurniture")
    own = cab.parts[CABINET].structure
    assert own.signature() == "0<R-1,0<R-2" and own != laptops.structure
    f = rendered[CABINET][0]
    want = re.escape(f"structure {own.signature()}, not the category's {laptops.structure.signature()}")
    with pytest.raises(KinmoDataError, match=want) as e:
        frame_sample(load_frame(f), cab.parts[CABINET], laptops.structure, path=f)
    assert str(f) in str(e.value)
    with pytest.raises(KinmoDataError, match="cannot be expressed by ANCSH"):
        frame_sample(load_frame(f), None, laptops.structure, path=f)
    if cab.structure != own:  # a category model of another structure rejects it too
        with pytest.raises(KinmoDataError, match=re.escape(f"not the category's {cab.structure.signature()}")):
            frame_sample(load_frame(f), cab.parts[CABINET], cab.structure, path=f)
    # the cabinet's own structure accepts it: 3 parts, 2 joints
    s = frame_sample(load_frame(f), cab.parts[CABINET], own, path=f)
    assert set(np.unique(s.seg)) <= {0, 1, 2} and set(np.unique(s.joint)) <= {0, 1, 2}


@pytest.mark.exactdata
def test_sibling_doors_are_ordered_top_to_bottom_then_left_to_right(mobility_root):
    shape, parts = object_parts_of(mobility_root / CABINET)
    assert parts.structure.signature() == "0<R-1,0<R-2"
    cen = link_centroids(shape)
    a, b = (cen[lid] for lid in parts.joint_links)
    # key: (-y, x): the first door is higher, or as high and further left
    assert (-a[1], a[0]) <= (-b[1], b[0])
    # every link of a rigid group shares its group's centroid and part
    from kinmo.data.labels import rigid_groups

    for lid, g in rigid_groups(shape.links).items():
        np.testing.assert_allclose(cen[lid], cen[g])
        assert parts.link_part[lid] == parts.link_part[g]
