"""Table 2 over ANCSH seeds (``kinmo train all --ancsh-seeds K``, issue 38): the report reads
each seed's ``table2 seed <s>`` stage from ``pipeline_result.json`` and gives per-seed means,
their mean ± sample standard deviation and range, per category, and semi-weakly's change."""

import json
import math

from kinmo.report.collect import collect_run
from kinmo.report.document import Heading, Table, Text
from kinmo.report.paper_tables import seed_spread, table2_seed_blocks

# rotation error per seed, setting and category (axis angle = rotation / 10)
ROT = {0: {"supervised": (50.0, 30.0), "semi-weakly": (40.0, 20.0)},
       1: {"supervised": (54.0, 32.0), "semi-weakly": (44.0, 28.0)},
       2: {"supervised": (52.0, 34.0), "semi-weakly": (42.0, 24.0)}}


def _write_eval(folder, seed, index):
    folder.mkdir(parents=True)
    lines = ["setting,run,frames,rotation_deg_mean,angle_deg_mean,rotation_deg_matched_mean"]
    for setting, vals in ROT[seed].items():
        v = vals[index]
        lines.append(f"{setting},r,24,{v},{v / 10},{v - 5}")  # matched columns are not read
    (folder / "table2.csv").write_text("\n".join(lines) + "\n")


def test_seed_spread():
    assert seed_spread([1.0, 2.0, 3.0]) == (2.0, 1.0, 1.0, 3.0)
    assert seed_spread([4.0, math.nan]) == (4.0, 0.0, 4.0, 4.0)
    assert all(math.isnan(x) for x in seed_spread([math.nan]))


def test_report_gives_table2_over_seeds(tmp_path):
    run = tmp_path / "run"
    stages = {"table2": []}
    for seed in ROT:
        root = run if seed == 0 else run / "ancsh-seeds" / f"seed-{seed}"
        dirs = []
        for i, cat in enumerate(("Laptop", "Safe")):
            _write_eval(root / "eval" / cat, seed, i)
            dirs.append(str(root / "eval" / cat))
        stages[f"table2 seed {seed}"] = dirs
        if seed == 0:
            stages["table2"] = dirs
    run.joinpath("pipeline_result.json").write_text(json.dumps({"out": str(run), "stages": stages}))
    art = collect_run(run)
    assert sorted(art.table2_seeds) == [0, 1, 2] and not art.problems
    # the run's own Table 2 is seed 0's alone
    assert art.table2.value("supervised", "mean", art.table2.rotation_column) == 40.0
    blocks = table2_seed_blocks(art.table2_seeds)
    assert isinstance(blocks[0], Heading) and blocks[0].text == "Table 2 over 3 ANCSH seeds"
    means = {tuple(r[:2]): r for r in blocks[1].rows}
    # supervised rotation: category means 40, 43, 43 -> 42.00 ± 1.73, range 40-43
    sup = means[("supervised", "rotation err (deg)")]
    assert sup[2:5] == ["40.00", "43.00", "43.00"] and sup[5:7] == ["42.00 ± 1.73", "40.00–43.00"]
    assert sup[7] == "23.66"  # the paper's
    assert means[("semi-weakly", "axis angle err (deg)")][5] == "3.30 ± 0.30"  # 3.0, 3.6, 3.3
    per_cat = blocks[2]
    assert isinstance(per_cat, Table) and per_cat.rows[0] == ["Laptop", "52.00 (50.00–54.00)",
                                                              "42.00 (40.00–44.00)"]
    text = blocks[3]
    assert isinstance(text, Text) and "seed 0 -25.0 %" in text.text and "seed 1 -16.3 %" in text.text


def test_one_seed_gives_no_seed_table(tmp_path):
    run = tmp_path / "run"
    _write_eval(run / "eval" / "Laptop", 0, 0)
    run.joinpath("pipeline_result.json").write_text(json.dumps(
        {"out": str(run), "stages": {"table2": [str(run / "eval" / "Laptop")]}}))
    art = collect_run(run)
    assert art.table2 is not None and art.table2_seeds == {} and table2_seed_blocks(art.table2_seeds) == []
