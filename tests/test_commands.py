"""The three commands users were promised (README "Use kinmo on real data"), exactly as written,
in a fresh folder holding a few real objects: ``kinmo prepare partnet/``, ``kinmo train all``,
``kinmo eval --category refrigerator`` (with ``KINMO_PRESET=tiny``, as the README documents)."""

import csv
import json
import shutil

import pytest
from typer.testing import CliRunner

from kinmo.cli import app

#: Refrigerators with one door (one kinematic structure: enough for 2 training + 1 test object)
#: and laptops, PartNet-Mobility; a refrigerator and a laptop of PartNet.
LABELED = ("10849", "10905", "12252", "10040", "10306", "10697")
UNLABELED = ("11299", "9960")


def _copy(src, dst, ids):
    for i in ids:
        shutil.copytree(src / i, dst / i)


@pytest.mark.exactdata
def test_prepare_train_all_eval_category_as_written(tmp_path, monkeypatch, mobility_root, partnet_root):
    _copy(mobility_root, tmp_path / "partnet-mobility", LABELED)
    _copy(partnet_root, tmp_path / "partnet", UNLABELED)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("KINMO_DATA", raising=False)
    monkeypatch.setenv("KINMO_PRESET", "tiny")
    runner = CliRunner()

    res = runner.invoke(app, ["prepare", "partnet/"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "cache/partnet/manifest.csv").is_file()

    res = runner.invoke(app, ["train", "all"])
    assert res.exit_code == 0, res.output
    # it says which data it found and why: PartNet from the prepared cache, PartNet-Mobility here
    assert "cache/partnet" in res.output and "./partnet-mobility in the current folder" in res.output
    plan = json.loads((tmp_path / "runs/all/ancsh/categories.json").read_text())
    assert set(plan["trained"]) == {"Laptop", "Refrigerator"}
    assert plan["trained"]["Refrigerator"][0]["structure"] == "0<R-1"

    res = runner.invoke(app, ["eval", "--category", "refrigerator"])
    assert res.exit_code == 0, res.output
    out = " ".join(res.output.split())
    assert "Refrigerator" in out and "runs/all/ancsh/Refrigerator" in out
    # the Table 2 row of each setting, next to the paper's means
    for setting, paper in (("supervised", "23.66"), ("semi", "24.76"), ("semi-weakly", "17.43")):
        assert setting in out and paper in out
    table = (tmp_path / "runs/all/ancsh/Refrigerator/eval-refrigerator/table2.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in table[1:]] == ["supervised", "semi", "semi-weakly"]

    # Table 1 the same way: the models of `kinmo train all`, the shapes they did not train on
    res = runner.invoke(app, ["eval", "pre-segmented", "--data", "runs/all/cache/labeled", "-q",
                              "--out", "t1"])
    assert res.exit_code == 0, res.output
    test = json.loads((tmp_path / "runs/all/split.json").read_text())["test"]
    with open(tmp_path / "t1/shapes.csv") as f:
        rows = list(csv.DictReader(f))
    assert {r["shape_id"] for r in rows} == set(test)
    assert {r["model"] for r in rows} == {"GNN_fine", "GNN_coarse", "OBB_fine", "OBB_coarse"}

    # out of fold on every labelled object, with the pseudo-label rule graded per fold (issue 34)
    res = runner.invoke(app, ["eval", "oof", "--data", "runs/all/cache/labeled", "--out", "oof",
                              "--folds", "3", "--preset", "quick", "-q"])
    assert res.exit_code == 0, res.output
    out = " ".join(res.output.split())
    assert f"pseudo-label rule at 0.6 out of fold: {len(LABELED)} objects" in out
    rule = json.loads((tmp_path / "oof/oof.json").read_text())["pseudo_rule"]
    assert rule["all"]["objects"] == len(LABELED) and set(rule["categories"]) <= {"Laptop", "Refrigerator"}
    assert "| **all** |" in (tmp_path / "oof/pseudo-label-rule/summary.md").read_text()


def test_train_all_without_data_names_what_to_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("KINMO_DATA", raising=False)
    res = CliRunner().invoke(app, ["train", "all"])
    assert res.exit_code == 1
    assert "kinmo prepare partnet-mobility/" in res.output
    assert "Traceback" not in res.output


def test_eval_category_without_runs_says_what_to_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["eval", "--category", "refrigerator"])
    assert res.exit_code == 1
    assert "kinmo train all" in res.output
    # a category `kinmo train all` left out: why (the counts) and the command that trains it
    ancsh = tmp_path / "runs/all/ancsh"
    ancsh.mkdir(parents=True)
    (ancsh / "categories.json").write_text(json.dumps(
        {"trained": {}, "skipped": {"Microwave": "1 training and 1 test objects fit 0<R-1"}}))
    res = CliRunner().invoke(app, ["eval", "--category", "microwaves"])
    assert res.exit_code == 1
    out = " ".join(res.output.split())
    assert "1 training and 1 test objects fit 0<R-1" in out
    assert "kinmo train all --category Microwave" in out


def _shape(folder, labeled):
    folder.mkdir(parents=True)
    (folder / "result.json").write_text("[]")
    if labeled:
        (folder / "mobility_v2.json").write_text("[]")


def test_find_data_rule(tmp_path):
    from kinmo.pipeline import find_data

    env = {"KINMO_DATA": str(tmp_path / "shared")}
    # 4. $KINMO_DATA/partnet-mobility and $KINMO_DATA/partnet
    _shape(tmp_path / "shared/partnet-mobility/1", True)
    _shape(tmp_path / "shared/partnet/2", False)
    here = tmp_path / "here"
    here.mkdir()
    f = find_data(here, env)
    assert f.labeled == tmp_path / "shared/partnet-mobility" and f.why_labeled == "$KINMO_DATA/partnet-mobility"
    assert f.unlabeled == tmp_path / "shared/partnet"
    # 3. ./partnet-mobility and ./partnet win over $KINMO_DATA
    _shape(here / "partnet-mobility/3", True)
    f = find_data(here, env)
    assert f.labeled == here / "partnet-mobility" and f.unlabeled == tmp_path / "shared/partnet"
    # 2. the source folders of the caches `kinmo prepare` wrote win over both: labelled or not
    for name, src, lab in (("mine", "mine", True), ("theirs", "theirs", False)):
        _shape(here / src / "4", lab)
        (here / "cache" / name).mkdir(parents=True)
        (here / "cache" / name / "manifest.json").write_text(json.dumps(
            {"root": src, "shapes": [{"source": f"{src}/4"}]}))
    f = find_data(here, env)
    assert (f.labeled, f.unlabeled) == (here / "mine", here / "theirs")
    assert "cache" in f.why_labeled and "kinmo prepare" in f.why_unlabeled
    # 1. given folders win over everything
    f = find_data(here, env, labeled=tmp_path / "x")
    assert f.labeled == tmp_path / "x" and f.why_labeled == "given on the command line"
    # nothing anywhere
    empty = tmp_path / "empty"
    empty.mkdir()
    assert find_data(empty, {}).labeled is None and find_data(empty, {}).unlabeled is None


@pytest.mark.exactdata
def test_split_by_structure_gives_refrigerator_a_model(mobility_root, tmp_path):
    """On the shared data, a category-stratified split leaves no test refrigerator of a structure
    with training objects; the split by category and structure does, so it gets a model."""
    from collections import Counter

    from kinmo.ancsh.dataset import scan_category
    from kinmo.pipeline import ancsh_plan, structure_split

    sp = structure_split(mobility_root, seed=0)
    cat = scan_category(mobility_root, "refrigerator")
    counts = Counter(p.structure for p in cat.parts.values() if p is not None)
    test = set(sp.test)
    for st, n in counts.items():  # every structure of 3+ objects: 2+ training, 1+ test objects
        fit = [i for i, p in cat.parts.items() if p is not None and p.structure == st]
        if n >= 3:
            assert sum(i in test for i in fit) >= 1 and sum(i not in test for i in fit) >= 2
    assert set(sp.train) | test == set(sp.categories) and not set(sp.train) & test
    sp.save(tmp_path / "split.json")
    plan, skipped = ancsh_plan(mobility_root, tmp_path / "split.json")
    assert "Refrigerator" in plan and "Refrigerator" not in skipped
    assert all(len(g.train) >= 2 and g.test for gs in plan.values() for g in gs)
    assert all("fit" in why or "no object" in why for why in skipped.values())


def _fake_pipeline(tmp_path, monkeypatch):
    """``run_pipeline`` replaced by one that records each configuration it gets (returned list);
    ``tmp_path/pm`` an empty labelled folder."""
    import kinmo.pipeline

    seen = []

    class _Res:
        report = tmp_path / "report"

    def fake_run(cfg, console=None):
        seen.append(cfg)
        return _Res()

    monkeypatch.setattr(kinmo.pipeline, "run_pipeline", fake_run)
    (tmp_path / "pm").mkdir()
    return seen


def test_train_all_release_synth_reaches_the_pipeline(tmp_path, monkeypatch):
    """``--release-synth N`` sets the release fine GNN's generated objects; without it, the
    configuration's default (RELEASE_SYNTH)."""
    from kinmo.pipeline.config import RELEASE_SYNTH

    seen = _fake_pipeline(tmp_path, monkeypatch)
    base = ["train", "all", "--labeled", str(tmp_path / "pm"), "--out", str(tmp_path / "run"), "--release"]
    for extra, want in (([], RELEASE_SYNTH), (["--release-synth", "7"], 7), (["--release-synth", "0"], 0)):
        res = CliRunner().invoke(app, base + extra)
        assert res.exit_code == 0, res.output
        assert seen[-1].release and seen[-1].release_synth == want
    assert RELEASE_SYNTH > 0
    res = CliRunner().invoke(app, base + ["--release-synth", "-1"])
    assert res.exit_code == 2 and len(seen) == 3


def test_eval_oof_extra_reaches_the_evaluation(tmp_path, monkeypatch):
    """``kinmo eval oof --extra CACHE`` passes the cache on (None without it)."""
    import kinmo.evaluate.oof
    from kinmo.evaluate.shape_metrics import EvalReport

    seen = []

    def fake(data, out, **kw):
        seen.append(kw["extra"])
        return kinmo.evaluate.oof.OOFResult(EvalReport([], [], {}, {}), None)

    monkeypatch.setattr(kinmo.evaluate.oof, "oof_table1", fake)
    base = ["eval", "oof", "--data", str(tmp_path / "c"), "--out", str(tmp_path / "o"), "-q"]
    for more, want in (([], None), (["--extra", str(tmp_path / "gen")], tmp_path / "gen")):
        res = CliRunner().invoke(app, base + more)
        assert res.exit_code == 0, res.output
        assert seen[-1] == want


def test_train_all_train_synth_reaches_the_pipeline(tmp_path, monkeypatch):
    """``--train-synth N`` sets the main run's generated training objects; without it, the
    configuration's default (TRAIN_SYNTH)."""
    from kinmo.pipeline.config import TRAIN_SYNTH

    seen = _fake_pipeline(tmp_path, monkeypatch)
    base = ["train", "all", "--labeled", str(tmp_path / "pm"), "--out", str(tmp_path / "run")]
    for extra, want in (([], TRAIN_SYNTH), (["--train-synth", "7"], 7), (["--train-synth", "0"], 0)):
        res = CliRunner().invoke(app, base + extra)
        assert res.exit_code == 0, res.output
        assert seen[-1].train_synth == want
    res = CliRunner().invoke(app, base + ["--train-synth", "-1"])
    assert res.exit_code == 2 and len(seen) == 3
    # the help gives the default the configuration has
    res = CliRunner().invoke(app, ["train", "all", "--help"], terminal_width=400)
    assert f"default {TRAIN_SYNTH}: none" in " ".join(res.output.split())
