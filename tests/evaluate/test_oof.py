"""``kinmo eval oof`` (issue 34): Table 1's four settings out of fold on every labelled object."""

from __future__ import annotations

import json
import math

import pytest

from kinmo.errors import KinmoDataError
from kinmo.evaluate.oof import SETTINGS, oof_table1
from kinmo.evaluate.pseudo_rule import grade_pseudo_rule
from kinmo.inference.predictor import Predictor
from kinmo.pseudo_label import PseudoLabelConfig
from kinmo.refine.config import RefineConfig
from kinmo.ranges import RangePrior
from kinmo.runs import member_folders
from kinmo.train.gnn import load_run
from motion_cabinet import cabinet_graph


def _graphs(n=6):
    gs = [cabinet_graph(n_points=32, seed=s, jitter=0.15, shape_id=f"cab{s}") for s in range(n)]
    for k, g in enumerate(gs):  # two categories, so that the per-category mean is a mean
        g.category = "A" if k % 2 else "B"
    return gs


def _no_nan(table):
    """The table with NaN (no joint to score) as None, so that equal tables compare equal."""
    return {k: {m: (None if isinstance(v, float) and math.isnan(v) else v) for m, v in row.items()}
            for k, row in table.items()}


def _held_out(out, k):
    return [json.loads((out / "folds" / f"fine_{f}" / "split.json").read_text())["test"] for f in range(k)]


def test_every_object_is_predicted_out_of_fold_in_four_settings(tmp_path):
    graphs = _graphs()
    report = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False).report
    assert report.models == list(SETTINGS)
    for m in SETTINGS:
        rows = report.shapes[m]
        assert sorted(r.shape_id for r in rows) == sorted(g.shape_id for g in graphs)
        assert report.table[(m, "all")]["n_shapes"] == len(graphs)
    # one GNN per fold and type set, each held out of its fold's objects
    for t in ("fine", "coarse"):
        held = []
        for f in range(3):
            split = json.loads((tmp_path / "folds" / f"{t}_{f}" / "split.json").read_text())
            assert not set(split["train"]) & set(split["test"])
            held += split["test"]
        assert sorted(held) == sorted(g.shape_id for g in graphs)
    assert sorted(p.name for p in (tmp_path / "rankers").iterdir()) == [
        f"ranker_{f}.json" for f in range(3)]
    # one range prior per fold, fit on the other folds' objects (one door hinge each)
    for f, held in enumerate(_held_out(tmp_path, 3)):
        prior = RangePrior.load(tmp_path / "ranges" / f"ranges_{f}.json")
        assert prior.lookup("hinge", None, None).n == len(graphs) - len(held)
    summary = json.loads((tmp_path / "oof.json").read_text())
    assert summary["objects"] == len(graphs) and summary["folds"] == 3
    assert set(summary["angle_joint"]) == set(SETTINGS)
    assert "gain_fine" in summary and "gain_coarse" in summary
    assert (tmp_path / "table1.md").is_file() and (tmp_path / "table1.csv").is_file()
    # a second run finds its folds trained and gives the same table
    again = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False).report
    assert _no_nan(again.table) == _no_nan(report.table)


def test_fewer_objects_than_folds_is_one_clear_error(tmp_path):
    with pytest.raises(KinmoDataError, match="fewer than --folds 5"):
        oof_table1(_graphs(3), tmp_path, folds=5, preset="tiny", epochs=1, progress=False)


def test_fold_gnns_get_their_ensemble_members_and_an_older_run_resumes(tmp_path):
    graphs = _graphs()
    single = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False).report
    stamp = {t: (tmp_path / "folds" / f"{t}_0" / "model.pt").stat().st_mtime_ns for t in ("fine", "coarse")}
    ens = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False, members=1).report
    for t in ("fine", "coarse"):
        for f in range(3):
            run_dir = tmp_path / "folds" / f"{t}_{f}"
            (member,) = member_folders(run_dir)
            cfg = json.loads((member / "config.json").read_text())
            assert cfg["seed"] == 1  # the fold's own seed + 1, on the fold's split
            assert json.loads((member / "split.json").read_text()) == json.loads((run_dir / "split.json").read_text())
        # the fold's own model was kept, only its member trained
        assert (tmp_path / "folds" / f"{t}_0" / "model.pt").stat().st_mtime_ns == stamp[t]
    assert json.loads((tmp_path / "oof.json").read_text())["members"] == 1
    assert ens.models == single.models
    assert len(load_run(tmp_path / "folds" / "fine_0", device="cpu").members) == 1  # predicted as one


def test_the_pseudo_label_rule_is_graded_out_of_fold_by_each_folds_models(tmp_path):
    graphs = _graphs()
    res = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False,
                     pseudo=PseudoLabelConfig(threshold=0.0))
    rule = res.pseudo_rule
    assert rule is not None and rule.threshold == 0.0
    # every labelled object graded once, by the models of the fold that held it out
    assert rule.n_objects == len(graphs)
    assert sorted({j.shape_id for j in rule.joints}) == sorted(g.shape_id for g in graphs)
    by_id = {g.shape_id: g for g in graphs}
    for f, held in enumerate(_held_out(tmp_path, 3)):
        cfg = RefineConfig(selector="ranker", ranker=str(tmp_path / "rankers" / f"ranker_{f}.json"))
        prior = RangePrior.load(tmp_path / "ranges" / f"ranges_{f}.json")
        fine = Predictor(load_run(tmp_path / "folds" / f"fine_{f}", "cpu"), None, cfg, ranges=prior)
        coarse = Predictor(load_run(tmp_path / "folds" / f"coarse_{f}", "cpu"), None, cfg, ranges=prior)
        direct = grade_pseudo_rule(fine, [by_id[i] for i in sorted(held)], PseudoLabelConfig(threshold=0.0),
                                   check=coarse)
        # (as text: a still joint's angle is NaN, which equals nothing)
        assert sorted(map(repr, direct.joints)) == sorted(repr(j) for j in rule.joints if j.shape_id in held)
    doc = json.loads((tmp_path / "oof.json").read_text())["pseudo_rule"]
    assert doc == json.loads((tmp_path / "pseudo-label-rule" / "summary.json").read_text())
    assert doc["threshold"] == 0.0 and doc["all"]["objects"] == len(graphs)
    assert "| **all** | 6 |" in (tmp_path / "pseudo-label-rule" / "summary.md").read_text()
    # not asked: not graded, not written; Table 1 is the same
    again = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False, pseudo_rule=False)
    assert again.pseudo_rule is None and _no_nan(again.report.table) == _no_nan(res.report.table)
    assert not (tmp_path / "pseudo-label-rule").exists()  # not the earlier run's
    assert "pseudo_rule" not in json.loads((tmp_path / "oof.json").read_text())


def test_a_fold_whose_selector_cannot_be_fit_is_one_clear_error(tmp_path, monkeypatch):
    import kinmo.train.ranker as ranker  # the fit both train all and eval oof go through

    def no_positive(*a, **k):
        raise ValueError("fit_ranker: no group with a positive candidate")

    monkeypatch.setattr(ranker, "fit_type_rankers", no_positive)
    with pytest.raises(KinmoDataError, match="fold 0: cannot fit the selector .* no group with a positive"):
        oof_table1(_graphs(), tmp_path, folds=3, preset="tiny", epochs=1, progress=False)


def test_extra_objects_join_every_folds_training_and_are_never_evaluated(tmp_path):
    graphs = _graphs()
    extra = [cabinet_graph(n_points=32, seed=10 + s, jitter=0.15, shape_id=f"gen{s}") for s in range(3)]
    for g in extra:
        g.category = "A"
    res = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False,
                     pseudo_rule=False, extra=extra)
    gen = {g.shape_id for g in extra}
    for t in ("fine", "coarse"):
        for f in range(3):
            split = json.loads((tmp_path / "folds" / f"{t}_{f}" / "split.json").read_text())
            assert gen <= set(split["train"]) and not gen & set(split["test"])
    assert sorted(sum(_held_out(tmp_path, 3), [])) == sorted(g.shape_id for g in graphs)
    for m in SETTINGS:  # only the real objects are scored
        assert sorted(r.shape_id for r in res.report.shapes[m]) == sorted(g.shape_id for g in graphs)
    # the range priors are fit on the other folds' real objects, not on the extra ones
    for f, held in enumerate(_held_out(tmp_path, 3)):
        prior = RangePrior.load(tmp_path / "ranges" / f"ranges_{f}.json")
        assert prior.lookup("hinge", None, None).n == len(graphs) - len(held)
    assert json.loads((tmp_path / "oof.json").read_text())["extra_training_objects"] == 3
    assert json.loads((tmp_path / "folds" / "extra.json").read_text()) == {"extra": sorted(gen)}
    # the same extra objects resume; other ones (or none) never mix with the trained folds
    again = oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False,
                       pseudo_rule=False, extra=extra)
    assert _no_nan(again.report.table) == _no_nan(res.report.table)
    for other in (None, extra[:2]):
        with pytest.raises(KinmoDataError, match="extra objects"):
            oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False,
                       pseudo_rule=False, extra=other)


def test_folds_trained_without_extra_objects_refuse_them(tmp_path):
    graphs = _graphs()
    oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False, pseudo_rule=False)
    (tmp_path / "folds" / "extra.json").unlink()  # an output of the time before --extra
    extra = [cabinet_graph(n_points=32, seed=20, shape_id="gen0")]
    with pytest.raises(KinmoDataError, match="trained with 0 extra objects, not these 1"):
        oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False,
                   pseudo_rule=False, extra=extra)


def test_an_extra_object_that_is_also_evaluated_is_one_clear_error(tmp_path):
    graphs = _graphs()
    with pytest.raises(KinmoDataError, match="also evaluated ones, e.g. 'cab1'"):
        oof_table1(graphs, tmp_path, folds=3, preset="tiny", epochs=1, progress=False,
                   extra=[cabinet_graph(n_points=32, seed=1, shape_id="cab1")])
    assert not (tmp_path / "folds").exists() or not any((tmp_path / "folds").glob("*/model.pt"))
