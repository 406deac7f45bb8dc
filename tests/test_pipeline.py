"""End to end: ``kinmo demo --tiny`` runs every stage on generated objects, and resumes."""

import csv
import json
from pathlib import Path

from typer.testing import CliRunner

from kinmo.cli import app

from browser import headless, images_loaded


def test_demo_runs_the_whole_pipeline_and_resumes(tmp_path, chromium, monkeypatch):
    runner = CliRunner()
    out = tmp_path / "demo"
    res = runner.invoke(app, ["demo", "--out", str(out), "--n", "12", "--tiny"])
    assert res.exit_code == 0, res.output
    run = out / "run"
    # every stage left its product
    for sub in ("split.json", "cache/labeled/manifest.csv", "cache/unlabeled/manifest.csv", "gnn_fine/model.pt",
                "gnn_coarse/model.pt", "axis", "ranker/ranker.json", "ranges/ranges.json",
                "model/ranges.json", "pseudo/summary.csv",
                "eval/pre-segmented-paper/table1.csv",
                "ancsh/Laptop/supervised/model.pt", "ancsh/Laptop/semi/model.pt",
                "ancsh/Laptop/semi-weakly/model.pt", "report/index.html", "report/report.md"):
        assert (run / sub).exists(), sub
    # the prepared caches hold every generated object
    with open(run / "cache/labeled/manifest.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 12 and all(r["status"] == "ok" for r in rows)
    # Table 1 and Table 2 were written with numbers
    t1 = list((run / "eval/pre-segmented").rglob("*.csv"))
    assert t1
    t2 = list((run / "eval/Laptop").rglob("table2.csv"))
    assert t2
    with open(t2[0]) as f:
        settings = {r["setting"] for r in csv.DictReader(f)}
    assert settings == {"supervised", "semi", "semi-weakly"}
    # the report shows both tables
    html = (run / "report/index.html").read_text()
    assert "Table 1" in html and "Table 2" in html
    result = json.loads((run / "pipeline_result.json").read_text())
    assert result["categories"] == ["Laptop"]
    # the split was made once, first, and recorded; every model trained on it
    split = json.loads((run / "split.json").read_text())
    assert result["split"] == str(run / "split.json") and result["stages"]["split"] == [str(run / "split.json")]
    assert json.loads((run / "gnn_fine/split.json").read_text())["test"] == split["test"]
    assert list(result["timings"])[:2] == ["generate 12 labelled + 6 unlabelled objects", "split"]
    # the learned selector: fit on out-of-fold GNNs of the training objects only (fold GNNs
    # of the tiny preset's epochs), used by Table 1's OBB rows and by the pseudo-labels
    assert result["selector"] == "learned" and result["stages"]["ranker"] == [str(run / "ranker")]
    ranker = json.loads((run / "ranker/ranker.json").read_text())
    assert ranker["meta"]["trained_on"]["split"] == str(run / "split.json")
    assert json.loads((run / "ranker/folds.json").read_text())["fine"]["epochs"] == 25  # the demo's --gnn-epochs
    fold_ids = {i for d in (run / "ranker/folds").iterdir() for i in json.loads((d / "split.json").read_text())["test"]}
    assert fold_ids == set(split["train"])
    ranker_file = str(run / "ranker" / "ranker.json")
    for t1 in ("eval/pre-segmented", "pseudo"):
        refine = json.loads((run / t1 / ".done").read_text())
        refine = refine.get("refine") or refine["pseudo"]["refine"]
        assert (refine["selector"], refine["ranker"]) == ("ranker", ranker_file), t1
    assert json.loads((run / "eval/pre-segmented-paper/.done").read_text())["refine"]["selector"] == "paper"
    # the pseudo-label rule graded on the labelled test objects, with the pseudo-labels' models
    rule = json.loads((run / "eval/pseudo-label-rule/summary.json").read_text())
    assert rule["threshold"] == 0.6 and rule["all"]["objects"] == len(split["test"])
    assert 0 <= rule["all"]["kept"] <= rule["all"]["objects"]
    assert json.loads((run / "eval/pseudo-label-rule/.done").read_text())["pseudo"]["refine"]["ranker"] == ranker_file
    assert result["stages"]["pseudo_rule"] == [str(run / "eval/pseudo-label-rule")]
    kept = list((run / "pseudo").glob("*/scores.json"))
    assert kept and all(json.loads(p.read_text())["options"]["refine"]["ranker"] == ranker_file for p in kept)
    # ... and the coarse GNN had to agree on each kept joint (issue 34)
    assert all(j["check_agrees"] is True for p in kept for j in json.loads(p.read_text())["joints"])
    assert all(json.loads(p.read_text())["models"]["check"] == str(run / "gnn_coarse") for p in kept)
    assert result["stages"]["table1"] == [str(run / "eval/pre-segmented"), str(run / "eval/pre-segmented-paper")]
    # the gallery shows the Table 1 renders of the test shapes, one per shape and model
    test = split["test"]
    renders = run / "eval/pre-segmented/renders"
    assert test and {p.stem for p in (renders / "GNN_fine").glob("*.png")} == set(test)
    assert {p.name for p in renders.iterdir()} == {"GNN_fine", "GNN_coarse", "OBB_fine", "OBB_coarse"}
    gallery = html.split('id="gallery"')[1]
    assert gallery.count("<img") == 4 * len(test) and "data:image/png;base64," in gallery
    # the model bundle: one folder that --model accepts whole, the learned selector by default
    bundle = json.loads((run / "model/bundle.json").read_text())
    assert (bundle["selector"], bundle["ranker"], bundle["axis"]) == ("ranker", "ranker.json", "axis")
    assert bundle["check"] == "check" and (run / "model/check/model.pt").read_bytes() == (
        run / "gnn_coarse/model.pt").read_bytes()
    assert bundle["trained_on"] == sorted(split["train"])
    assert result["stages"]["model"] == [str(run / "model")]
    obj = out / "data" / "partnet-mobility" / test[0]
    pr = runner.invoke(app, ["predict", str(obj), "--model", str(run / "model"), "--out",
                             str(tmp_path / "pred"), "--quiet", "--device", "cpu"])
    assert pr.exit_code == 0, pr.output
    assert (tmp_path / "pred" / test[0] / "mobility_v2.json").is_file()
    # every stage was timed, and the overview shows the times
    timings = result["timings"]
    assert {"generate 12 labelled + 6 unlabelled objects", "split", "prepare labelled", "train gnn (fine)",
            "train axis", "train ranker", "model bundle", "eval pre-segmented (Table 1)",
            "eval pre-segmented, paper selector (Table 1)",
            "pseudo-label", "train ancsh Laptop (semi-weakly)", "eval Laptop (Table 2)", "report"} <= set(timings)
    assert all(t["ran"] and t["cpu_s"] >= 0 and t["wall_s"] >= 0 for t in timings.values())
    assert timings["train gnn (fine)"]["cpu_s"] > 0
    assert "train ancsh Laptop (semi-weakly)" in html.split('id="table1"')[0]
    # the demo's own report, opened in a real browser: every image decodes
    dom = headless(chromium, tmp_path, "--dump-dom", (run / "report/index.html").as_uri())
    assert dom.returncode == 0, dom.stderr[-2000:]
    ok, total = images_loaded(dom.stdout)
    assert total >= 4 * len(test) and ok == total, f"{ok} of {total} images decoded"

    # the release bundle (`kinmo train all --release`): the recipe again on every labelled
    # object and the kept pseudo-labels; the baseline's stages are not run again
    from kinmo.pipeline import PipelineConfig, run_pipeline

    cfg = PipelineConfig.model_validate_json((run / "pipeline.json").read_text())
    # (with 4 generated objects for its fine GNN, where the default is 120)
    res3 = run_pipeline(cfg.model_copy(update={"release": True, "release_synth": 4}), progress=False)
    ran = {k for k, t in res3.timings.items() if t.ran and not k.startswith("release: train 3 models")}  # the pool
    assert ran == {
        "release: prepare pseudo-labels", "release: generate", "release: prepare generated",
        "release: train gnn (fine)", "release: train gnn (coarse)",
        "release: train axis", "release: fit range prior", "release: model bundle", "report"}
    rb = json.loads((run / "release/model/bundle.json").read_text())
    # its check/ is the release coarse GNN, so pseudo-labelling with the bundle needs agreement
    assert rb["check"] == "check" and (run / "release/model/check/model.pt").read_bytes() == (
        run / "release/gnn_coarse/model.pt").read_bytes()
    assert json.loads((run / "release/gnn_coarse/config.json").read_text())["model"]["types"] == "coarse"
    pseudo_ids = {p.parent.name for p in (run / "pseudo").glob("*/mobility_v2.json")}
    real_ids = set(split["train"]) | set(split["test"]) | pseudo_ids
    generated = {p.parent.name for p in (run / "release/generated").glob("*/mobility_v2.json")}
    assert len(generated) == 4 and not generated & real_ids
    assert pseudo_ids and set(rb["trained_on"]) == real_ids | generated
    assert (rb["selector"], rb["axis"], rb["ranges"]) == ("ranker", "axis", "ranges.json")
    # the generated objects train the fine GNN only
    assert json.loads((run / "release/gnn_fine/split.json").read_text())["test"] == []
    assert set(json.loads((run / "release/gnn_fine/split.json").read_text())["train"]) == real_ids | generated
    assert set(json.loads((run / "release/gnn_coarse/split.json").read_text())["train"]) == real_ids
    axis_split = json.loads((run / "release/axis/config.json").read_text())["split"]
    assert not set(axis_split["train"] + axis_split["val"]) & generated
    # eval leaves a bundle's training objects out: here all of them, so it refuses in one line
    ev = runner.invoke(app, ["eval", "pre-segmented", "--model", str(run / "release/model"), "--data",
                             str(run / "cache/labeled"), "--out", str(tmp_path / "ev"), "--quiet"])
    assert ev.exit_code == 1 and "the model bundle was trained on" in ev.output, ev.output

    # Table 2 over ANCSH seeds (issue 38): only the extra seed's trainings and evaluations run,
    # into ancsh-seeds/seed-1/, scored on the seed's own models and the same test scans
    res4 = run_pipeline(cfg.model_copy(update={"ancsh_seeds": 2}), progress=False)
    ran = {k for k, t in res4.timings.items() if t.ran and not k.startswith("train ancsh:")}  # less the pool's line
    assert ran == {"train ancsh Laptop (supervised, seed 1)", "train ancsh Laptop (semi, seed 1)",
                   "train ancsh Laptop (semi-weakly, seed 1)", "eval Laptop (Table 2, seed 1)", "report"}
    s1 = run / "ancsh-seeds" / "seed-1"
    assert json.loads((s1 / "ancsh/Laptop/supervised/config.json").read_text())["seed"] == 1
    assert res4.stages["table2 seed 0"] == [str(run / "eval/Laptop")]
    assert res4.stages["table2 seed 1"] == [str(s1 / "eval/Laptop")]
    assert res4.stages["table2"] == [str(run / "eval/Laptop")]
    with open(s1 / "eval/Laptop/table2.csv") as f:
        seed1 = {r["setting"]: r for r in csv.DictReader(f)}
    with open(t2[0]) as f:
        seed0 = {r["setting"]: r for r in csv.DictReader(f)}
    assert seed1.keys() == seed0.keys() and seed1["supervised"]["frames"] == seed0["supervised"]["frames"]
    assert seed1["supervised"]["rotation_deg_mean"] != seed0["supervised"]["rotation_deg_mean"]
    md = (run / "report/report.md").read_text()
    assert "Table 2 over 2 ANCSH seeds" in md and "Semi-weakly against supervised" in md
    seeds_md = md.split("Table 2 over 2 ANCSH seeds")[1]
    assert "| Laptop |" in seeds_md.split("Semi-weakly against supervised")[0]  # the per-category rows

    # a stage read by others trained again makes them stale, though their keys name it by
    # path: seed 1's supervised ANCSH run (a new marker) -> its semi and semi-weakly runs (semi
    # starts from it; semi-weakly takes its weights when no pseudo-label fits) and its evaluation
    from kinmo.pipeline.stages import mark_done

    sup = s1 / "ancsh/Laptop/supervised"
    mark_done(sup, json.loads((sup / ".done").read_text()))
    res5 = run_pipeline(cfg.model_copy(update={"ancsh_seeds": 2}), progress=False)
    ran = {k for k, t in res5.timings.items() if t.ran and not k.startswith("train ancsh:")}
    assert ran == {"train ancsh Laptop (semi, seed 1)", "train ancsh Laptop (semi-weakly, seed 1)",
                   "eval Laptop (Table 2, seed 1)", "report"}

    # a second run resumes: every stage but the report is up to date
    res2 = runner.invoke(app, ["demo", "--out", str(out), "--n", "12", "--tiny"])
    assert res2.exit_code == 0, res2.output
    assert "up to date" in res2.output
    assert "train gnn (fine) ->" not in res2.output
    timings2 = json.loads((run / "pipeline_result.json").read_text())["timings"]
    assert {k for k, t in timings2.items() if t["ran"]} == {"report"}
    # the same run folder spelt relative to another directory resumes too: stage keys hold
    # paths, made absolute by PipelineConfig (else every cache, then every stage, ran again)
    cwd = Path.cwd()
    monkeypatch.chdir(tmp_path)
    res2b = runner.invoke(app, ["demo", "--out", out.name, "--n", "12", "--tiny"])
    assert res2b.exit_code == 0, res2b.output
    timings2b = json.loads((run / "pipeline_result.json").read_text())["timings"]
    assert {k for k, t in timings2b.items() if t["ran"]} == {"report"}
    monkeypatch.chdir(cwd)

    # generated objects as ANCSH data (--ancsh-synth, issue 38): Laptop is made by kinmo synth,
    # so its three ANCSH settings train again with them, and Table 2 is scored again on the
    # same real test objects
    res6 = run_pipeline(cfg.model_copy(update={"ancsh_synth": 2, "ancsh_synth_as": "pretrain"}), progress=False)
    ran = {k for k, t in res6.timings.items() if t.ran and not k.startswith("train ancsh:")}
    assert ran == {"train ancsh Laptop (supervised)", "train ancsh Laptop (semi)",
                   "train ancsh Laptop (semi-weakly)", "eval Laptop (Table 2)", "report"}
    for setting in ("supervised", "semi-weakly"):
        info = json.loads((run / "ancsh/Laptop" / setting / "data.json").read_text())
        assert len(info["generated_objects"]) == 2 and not set(info["generated_objects"]) & set(split["test"])
    assert json.loads((run / "ancsh/Laptop/supervised/.done").read_text())["ancsh"]["synth_as"] == "pretrain"
    assert res6.ancsh_synth == {"objects": 2, "as": "pretrain", "without": {}}
    assert "include 2 generated objects" in (run / "report/report.md").read_text()

    # the part graphs computed another way (CACHE_VERSION, e.g. issue 36's OBB fit): the
    # caches are prepared again and the stages that learn from them train again, though
    # their configuration is unchanged; the ANCSH supervised run, which reads meshes and not
    # graphs, stays
    import kinmo.pipeline.run as pipeline_run

    monkeypatch.setattr(pipeline_run, "CACHE_VERSION", pipeline_run.CACHE_VERSION + 1)
    res7 = run_pipeline(cfg.model_copy(update={"ancsh_synth": 2, "ancsh_synth_as": "pretrain"}), progress=False)
    ran = {k for k, t in res7.timings.items() if t.ran}
    assert {"prepare labelled", "prepare unlabelled", "train gnn (fine)", "train gnn (coarse)", "train axis",
            "fit range prior"} <= ran, ran
    assert "train ranker" in ran, ran
    # and the ranker's fold GNNs, every one (their folds.json names the graphs' version)
    folds = {f"train ranker: fold GNN {d.name}" for d in (run / "ranker/folds").iterdir()}
    assert folds and folds <= ran, ran
    assert json.loads((run / "ranker/folds.json").read_text())["graphs"] == pipeline_run.CACHE_VERSION
    assert "train ancsh Laptop (supervised)" not in ran, ran

    # generated objects in the motion GNNs' and the ranker's fold GNNs' training (issue 34,
    # --train-synth): their own split, the real test objects; the axis network and the range
    # prior stay as they were
    res8 = run_pipeline(cfg.model_copy(update={"ancsh_synth": 2, "ancsh_synth_as": "pretrain", "train_synth": 3,
                                               "skip_ancsh": True}), progress=False)
    ran = {k for k, t in res8.timings.items() if t.ran}
    assert {"generate", "prepare generated", "train gnn (fine)", "train gnn (coarse)", "train ranker",
            "model bundle", "eval pre-segmented (Table 1)", "pseudo-label"} <= ran, ran
    assert not {"train axis", "fit range prior", "prepare labelled"} & ran, ran
    gen = {p.parent.name for p in (run / "generated").glob("*/mobility_v2.json")}
    assert len(gen) == 3 and not gen & (set(split["train"]) | set(split["test"]))
    gsplit = json.loads((run / "split_gnn.json").read_text())
    assert gsplit["train"] == sorted(split["train"] + list(gen)) and gsplit["test"] == split["test"]
    for t in ("fine", "coarse"):
        assert json.loads((run / f"gnn_{t}/split.json").read_text())["train"] == gsplit["train"]
    for d in (run / "ranker/folds").iterdir():  # in every fold's training, never held out
        fs = json.loads((d / "split.json").read_text())
        assert gen <= set(fs["train"]) and set(fs["test"]) <= set(split["train"]), d.name
    assert json.loads((run / "ranker/folds.json").read_text())["synth"]["n"] == 3
    assert json.loads((run / "model/bundle.json").read_text())["trained_on"] == gsplit["train"]
    with open(run / "eval/pre-segmented/shapes.csv") as f:
        assert {r["shape_id"] for r in csv.DictReader(f)} == set(split["test"])
    axis_split = json.loads((run / "axis/config.json").read_text())["split"]
    assert not set(axis_split["train"] + axis_split["val"]) & gen


def test_demo_passes_the_selector_to_the_pipeline(tmp_path, monkeypatch):
    import kinmo.pipeline.demo as demo

    seen = {}
    monkeypatch.setattr(demo, "run_pipeline", lambda cfg, **kw: seen.setdefault("cfg", cfg))
    demo.run_demo(tmp_path, n_labeled=2, n_unlabeled=2, tiny=True, progress=False, selector="paper")
    assert seen["cfg"].selector == "paper"
    seen.clear()
    demo.run_demo(tmp_path, n_labeled=2, n_unlabeled=2, tiny=True, progress=False)
    assert seen["cfg"].selector == "learned"
    # its labelled objects are generated already: no more for its motion GNNs, tiny or not
    assert seen["cfg"].train_synth == 0
    seen.clear()
    demo.run_demo(tmp_path, n_labeled=2, n_unlabeled=2, tiny=False, progress=False)
    assert seen["cfg"].train_synth == 0
