"""bench/bench_throughput.py: one kinmo timed against another (``--against``)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from repo_scripts import load_script


@pytest.fixture(scope="module")
def bench():
    return load_script("bench/bench_throughput.py")


def _row(kinmo: str, wall: float, cpu: float, stage: str = "predict", jobs: int = 2) -> dict:
    return dict(stage=stage, jobs=jobs, kinmo=kinmo, shapes=10, wall_s=wall, shapes_per_s=10 / wall,
                cpu_s_per_shape=cpu, load_before=0.0, load_after=0.0, exit_code=0)


def test_against_lines_give_this_kinmos_time_against_the_others(bench):
    rows = [_row("this", 12.0, 0.30), _row("/b", 10.0, 0.25),
            _row("this", 11.0, 0.28), _row("/b", 10.0, 0.20),
            _row("this", 13.0, 0.33), _row("/b", 11.0, 0.30),
            _row("this", 5.0, 0.1, stage="render")]  # no other run of render: no line
    (line,) = bench.against_lines(rows)
    # medians 10 -> 12 (+20 %); paired ratios 1.2, 1.1, 1.18 -> median +18.2 %
    assert line.startswith("| predict | 2 | 3 | 10.000 -> 12.000 (+20.0%; paired +18.2%)")
    # CPU: medians 0.25 -> 0.30; paired 1.2, 1.4, 1.1 -> +20 %
    assert line.endswith("0.250 -> 0.300 (+20.0%; paired +20.0%) |")


def test_a_run_against_another_kinmo_puts_its_package_first(bench, monkeypatch, tmp_path):
    seen = []

    def fake_run(cmd, env, **kw):
        seen.append(env.get("PYTHONPATH"))
        return subprocess.CompletedProcess(cmd, 0, stdout="")

    monkeypatch.setattr(bench.subprocess, "run", fake_run)
    monkeypatch.setattr(bench, "_count", lambda *a: 4)
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    other = tmp_path / "base" / "python"
    mine = bench.run_stage("predict", tmp_path, tmp_path, 2)
    theirs = bench.run_stage("predict", tmp_path, tmp_path, 2, other)
    assert seen == ["/elsewhere", os.pathsep.join([str(other.resolve()), "/elsewhere"])]
    assert mine["kinmo"] == "this" and theirs["kinmo"] == str(other) and theirs["shapes"] == 4


def test_against_refuses_a_folder_without_kinmo(bench, monkeypatch, tmp_path):
    monkeypatch.setattr("sys.argv", ["bench_throughput.py", "--against", str(tmp_path), "--out",
                                     str(tmp_path / "t.csv")])
    with pytest.raises(SystemExit, match="no kinmo package there"):
        bench.main()
    (tmp_path / "kinmo").mkdir()
    (tmp_path / "kinmo" / "__init__.py").write_text("")
    monkeypatch.setattr("sys.argv", ["bench_throughput.py", "--against", str(tmp_path), "--stages",
                                     "predict,predict-no-ranges"])
    with pytest.raises(SystemExit, match="predict-no-ranges"):
        bench.main()
    assert not Path(tmp_path / "t.csv").exists()
