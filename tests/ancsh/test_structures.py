"""Categories with several kinematic structures: one ANCSH model per structure, each test object
evaluated with the model of its structure, one aggregated row; and evaluation on a folder of
objects the runs never saw (``kinmo eval --category C --data DIR``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from kinmo.ancsh.config import preset
from kinmo.ancsh.dataset import scan_category
from kinmo.ancsh.evaluate import evaluate_category
from kinmo.ancsh.structure import category_structures, structure_groups, structure_slug
from kinmo.ancsh.train import train_ancsh
from kinmo.train.split import Split

#: Boxes: one lid (0<R-1) and four flaps (0<R-1,0<R-2,0<R-3,0<R-4); two training + one test each.
ONE_LID = ("102379", "102456", "100685")
FOUR_FLAPS = ("100154", "100162", "102373")


def _link(folder: Path, root: Path, ids) -> Path:
    folder.mkdir(parents=True)
    for i in ids:
        (folder / i).symlink_to(root / i, target_is_directory=True)
    return folder


@pytest.mark.exactdata
def test_structure_groups_count_training_and_test_objects(mobility_root):
    cat = scan_category(mobility_root, "box")
    structures = category_structures(cat.parts)
    assert structures[0][0] == cat.structure  # most common first, as category_structure picks
    assert sum(len(ids) for _, ids in structures) == sum(p is not None for p in cat.parts.values())
    test = {ONE_LID[2], FOUR_FLAPS[2]}
    kept, rest = structure_groups(cat.parts, test)
    sigs = {g.structure.signature(): g for g in kept}
    assert set(sigs) >= {"0<R-1", "0<R-1,0<R-2,0<R-3,0<R-4"}
    assert sigs["0<R-1"].test == (ONE_LID[2],) and set(ONE_LID[:2]) <= set(sigs["0<R-1"].train)
    assert all(len(g.train) < 2 or not g.test for g in rest)
    assert structure_slug(sigs["0<R-1,0<R-2,0<R-3,0<R-4"].structure) == "0R1-0R2-0R3-0R4"


@pytest.mark.exactdata
def test_one_model_per_structure_and_new_objects(mobility_root, tmp_path):
    data = _link(tmp_path / "data", mobility_root, ONE_LID + FOUR_FLAPS)
    split = tmp_path / "split.json"
    Split(sorted(ONE_LID[:2] + FOUR_FLAPS[:2]), sorted([ONE_LID[2], FOUR_FLAPS[2]])).save(split)
    cfg = preset("quick", epochs=1, steps_per_epoch=2, frames_per_object=1, batch_size=2, render_workers=1,
                 threads=1, test_frames_per_object=1)
    cat = scan_category(data, "Box")
    runs = tmp_path / "runs" / "Box"
    for st, _ in category_structures(cat.parts):
        res = train_ancsh("box", "supervised", runs / structure_slug(st) / "supervised", cfg, data=data,
                          split=split, scans=tmp_path / "scans", progress=False, structure=st)
        assert res.structure == st
        assert set(json.loads((res.run_dir / "data.json").read_text())["labeled_objects"]) < set(ONE_LID + FOUR_FLAPS)

    rows, paths = evaluate_category("box", [runs], out=tmp_path / "eval", progress=False, workers=1)
    info = json.loads(paths["json"].read_text())
    # each test object with the model of its structure, one row over both
    assert info["structures"] == {"0<R-1": [ONE_LID[2]], "0<R-1,0<R-2,0<R-3,0<R-4": [FOUR_FLAPS[2]]}
    assert [r.setting for r in rows] == ["supervised"] and rows[0].frames == 2
    md = paths["markdown"].read_text()
    assert "2 kinematic structures" in md and "## Table 2 — Box (structure 0<R-1)" in md
    assert 0 <= rows[0].mean("iou") <= 1 and rows[0].mean("angle_deg") <= 90

    # another folder: every fitting object the runs did not train on, training objects left out
    new = _link(tmp_path / "new", mobility_root, (ONE_LID[0], FOUR_FLAPS[2]))
    rows, paths = evaluate_category("box", [runs], data=new, out=tmp_path / "eval-new", progress=False, workers=1)
    info = json.loads(paths["json"].read_text())
    assert info["test_objects"] == [FOUR_FLAPS[2]] and info["refused_trained"] == [ONE_LID[0]]
    assert rows[0].frames == 1
