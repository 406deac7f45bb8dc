"""``kinmo train all --synth-extra N``: the pipeline trained again with generated shapes added,
evaluated on the same real test objects, and the report's comparison."""

import csv
import json

import pytest

from kinmo.pipeline import PipelineConfig, run_pipeline
from kinmo.synth import generate_dataset
from kinmo.train.split import Split

CATS = ["Laptop", "Refrigerator"]


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def _tiny(data, out, **kw) -> PipelineConfig:
    return PipelineConfig(labeled=data / "partnet-mobility", unlabeled=data / "partnet", out=out, gnn_epochs=1,
                          axis_epochs=1, skip_ancsh=True, render=False, workers=1, train_synth=0, **kw)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One run folder: the baseline with 4 generated labelled objects, then 2 generated
    unlabelled shapes added to the same folder. Stand-ins for the real data are generated
    objects of other seeds."""
    root = tmp_path_factory.mktemp("synth-extra")
    data = root / "data"
    generate_dataset(data / "partnet-mobility", 8, 3, categories=CATS, progress=False)
    generate_dataset(data / "partnet", 2, 4, categories=CATS, partnet=True, progress=False)
    out = root / "run"
    first = run_pipeline(_tiny(data, out, synth_extra=4, synth_seed=7), progress=False)
    second = run_pipeline(_tiny(data, out, synth_extra=2, synth_as="unlabeled", synth_seed=8), progress=False)
    return out, first, second


def test_generated_labeled_objects_join_training_only(runs):
    out, first, _ = runs
    v = out / "synth-extra-labeled-4"
    assert first.synth_extra == v
    base = Split.load(out / "split.json")
    with_gen = Split.load(v / "split.json")
    generated = {p.name for p in (v / "data" / "partnet-mobility").iterdir() if p.is_dir()}
    assert len(generated) == 4 and all(g.startswith("900007") for g in generated)
    # the same real test objects; every generated object is a training object
    assert with_gen.test == base.test and base.test
    assert generated <= set(with_gen.train) and not generated & set(base.train)
    assert set(with_gen.train) - generated == set(base.train)
    info = json.loads((v / "synth_extra.json").read_text())
    assert info["n"] == 4 and info["as"] == "labeled" and info["test"] == base.test
    assert info["categories"] == CATS
    # the baseline's ranker (fit on real training objects) selects the axes of both
    assert not (v / "ranker").exists() and first.stages["synth-extra: ranker"] == [str(out / "ranker")]
    # both Table 1 evaluations cover the same real test objects
    t_base = _rows(out / "eval/pre-segmented/table1.csv")
    t_gen = _rows(v / "eval/pre-segmented/table1.csv")
    assert {r["model"] for r in t_gen} == {r["model"] for r in t_base} == {
        "GNN_fine", "GNN_coarse", "OBB_fine", "OBB_coarse"}
    n_base = {r["n_shapes"] for r in t_base if r["category"] == "mean"}
    assert n_base == {r["n_shapes"] for r in t_gen if r["category"] == "mean"} == {str(len(base.test))}
    # its own models pseudo-labelled the real unlabelled shapes again
    assert int({r["category"]: r for r in _rows(v / "pseudo/summary.csv")}["all"]["shapes"]) == 2
    # every stage was timed
    t = first.timings
    assert {"prepare labelled", "train gnn (fine)", "synth-extra: generate", "synth-extra: train gnn (fine)",
            "synth-extra: eval pre-segmented (Table 1)", "synth-extra: pseudo-label", "report"} <= set(t)
    assert all(x.ran and x.wall_s >= 0 and x.cpu_s >= 0 for x in t.values())
    assert t["synth-extra: train axis"].cpu_s > 0
    assert json.loads((out / "pipeline_result.json").read_text())["timings"].keys() >= {"report"}


def test_generated_unlabeled_shapes_are_pseudo_labelled(runs):
    out, _, second = runs
    v = out / "synth-extra-unlabeled-2"
    # the baseline was up to date; its GNN and axis network label the generated shapes
    assert not any(t.ran for k, t in second.timings.items() if not k.startswith("synth-extra") and k != "report")
    assert not (v / "gnn_fine").exists() and not (v / "eval").exists()
    assert len(list((v / "data" / "unlabeled").iterdir())) == 2 + 2
    assert int({r["category"]: r for r in _rows(v / "pseudo/summary.csv")}["all"]["shapes"]) == 4
    assert int({r["category"]: r for r in _rows(out / "pseudo/summary.csv")}["all"]["shapes"]) == 2


def test_report_compares_with_and_without(runs):
    out, _, _ = runs
    html = (out / "report" / "index.html").read_text()
    md = (out / "report" / "report.md").read_text()
    main, _, rest = md.partition("## Generated shapes: with vs without")
    assert rest, "no comparison section"
    section = rest.split("\n## ")[0]
    # both runs with generated shapes are compared; the labelled one on Table 1
    assert "`synth-extra-labeled-4`: 4 generated objects" in section
    assert "`synth-extra-unlabeled-2`: 2 generated objects" in section
    assert "never see unlabelled shapes" in section
    rows = [r for r in section.splitlines() if r.startswith("| OBB_fine | angle err edges")]
    assert len(rows) == 2 and all(len(r.split("|")) == 7 for r in rows)  # learned and paper selector
    assert "#### Table 1 (eval/pre-segmented/table1.csv)" in section
    assert "#### Table 1 (eval/pre-segmented-paper/table1.csv)" in section
    assert "Table 1: the generated shapes" in section
    # the runs with generated shapes stay out of the other sections
    assert "synth-extra-" not in main and "synth-extra-" not in md.split("## Training")[1]
    assert "Generated shapes: with vs without" in html
    # the overview lists the time of every stage of the last call
    timing = [r for r in main.splitlines() if r.startswith("| synth-extra: pseudo-label |")]
    assert len(timing) == 1 and float(timing[0].split("|")[3]) > 0


def test_no_generated_category_is_an_error(tmp_path):
    from kinmo.errors import KinmoError

    lab = tmp_path / "pm"
    generate_dataset(lab, 4, 0, categories=["Laptop"], progress=False)
    for meta in lab.glob("*/meta.json"):
        m = json.loads(meta.read_text())
        m["model_cat"] = "Chair"
        meta.write_text(json.dumps(m))
    with pytest.raises(KinmoError, match="none of the labelled categories"):
        run_pipeline(PipelineConfig(labeled=lab, out=tmp_path / "run", synth_extra=2), progress=False)
    assert not (tmp_path / "run" / "gnn_fine").exists()  # before any training
