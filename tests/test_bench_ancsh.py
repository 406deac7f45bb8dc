"""bench/bench_ancsh.py (issue 38): the training-step mode reports the step-time targets it
measures, met or not."""

from __future__ import annotations

from repo_scripts import load_script


def _script():
    return load_script("bench/bench_ancsh.py")


def _results(device: str, quick_speedup: float, paper_fit_s: float) -> dict:
    # the overlapped loop under the target while fit is over it (or the reverse): fit decides
    return {"device": device, "presets": {"quick": {"speedup": quick_speedup, "overlap_step_s": 0.02,
                                                    "fit_step_s": 0.02},
                                          "paper": {"speedup": 1.1, "overlap_step_s": 0.06 - paper_fit_s,
                                                    "fit_step_s": paper_fit_s}}}


def test_cpu_run_checks_the_quick_speedup_only():
    b = _script()
    rows = b._step_targets(_results("cpu", 1.51, 1.6))
    assert [r["met"] for r in rows] == [True]
    assert "quick, CPU" in rows[0]["text"] and rows[0]["text"].endswith(", met")
    rows = b._step_targets(_results("cpu", 1.3, 1.6))
    assert [r["met"] for r in rows] == [False] and rows[0]["text"].endswith("NOT met")


def test_gpu_run_checks_the_paper_step():
    b = _script()
    rows = b._step_targets(_results("cuda", 1.0, 0.0255))
    assert [(r["target"].split(",")[0], r["met"]) for r in rows] == [("paper", True)]
    assert "of fit" in rows[0]["target"]
    rows = b._step_targets(_results("cuda:0", 1.0, 0.031))
    assert [r["met"] for r in rows] == [False]
