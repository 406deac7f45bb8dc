"""Throughput of the per-shape commands as users run them, with cold caches (issue 24, item 4).

Each stage is the ``kinmo`` command itself, run in a child process with its default model
(the pretrained bundle) and default outputs, into an empty output folder, with an empty
convex-decomposition cache (``KINMO_VHACD_CACHE`` pointing to an empty folder) and no part
graph cache, as for a dataset seen for the first time:

- ``pseudo-label``: ``kinmo pseudo-label PARTNET -o OUT -j 2 -q``;
- ``predict``: ``kinmo predict PARTNET -o OUT -j 2 -q``;
- ``predict-no-ranges``: the same with a copy of the pretrained bundle without its range
  prior (``ranges.json``), i.e. the tree's constant default ranges: the baseline of issue 35's
  cost check (a range for every joint may cost at most 20 % of ``predict``'s time);
- ``render``: ``kinmo render MOBILITY -o OUT -j 2 -q`` (its defaults: 10 frames of 256 x 256
  per object).

``-j 2`` unless ``--jobs`` says otherwise: ``--jobs 1,2`` runs each stage with one process
and with two workers, alternating within each repeat, and gives the speed-up of each over
the first. Within each repeat every stage runs once, so a change of load on the machine
hits the stages alike.

``--against SRC`` times another kinmo beside this one: SRC is the ``python/`` folder of
another checkout, its Rust core built in place (``maturin develop`` there, or ``cargo build
--release -p kinmo-py --features pyo3/extension-module`` and the library copied to
``SRC/kinmo/_core.<ext>``). Each run of a stage is followed by the same run with
``PYTHONPATH=SRC``, so both meet the same load, and the table gives this checkout's time
against the other's (ratio of the medians, and the median of the per-repeat ratios): the
before / after check of a change, or of a branch against the baseline commit an issue
names (issues 35 and 36: ``kinmo predict`` time per object at most 20 % above it;
``docs/results/scaling.md``). Each kinmo runs with its own default bundle.

Reported per stage: shapes, wall seconds, shapes per second on this machine, CPU seconds
(user + system of the command and every process it started, from ``RUSAGE_CHILDREN``) per
shape, and the 1-minute load average before and after (anything above ~0 besides the stage
itself is someone else's work on the cores). Each stage runs ``--repeats`` times; the table
gives the medians.

Usage::

    python bench/bench_throughput.py [--partnet ../shared/data/partnet]
        [--mobility ../shared/data/partnet-mobility]
        [--stages pseudo-label,predict,predict-no-ranges,render]
        [--repeats 1] [--jobs 2]      # --jobs 1,2: one process against two workers
        [--against ../kinmo-495ecc8/python]   # another checkout's package, alternating

Prints a Markdown table and writes ``bench/results/throughput.csv``; ``docs/results/scaling.md``
extrapolates the CPU seconds per shape to PartNet's 26,671 shapes.
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "throughput.csv"
SHARED = REPO.parent / "shared" / "data"


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _command(stage: str, partnet: Path, mobility: Path, out: Path, jobs: int = 2) -> list[str]:
    kinmo = [sys.executable, "-m", "kinmo"]
    j = ["-j", str(jobs)]
    if stage == "pseudo-label":
        return kinmo + ["pseudo-label", str(partnet), "-o", str(out), *j, "-q"]
    if stage == "predict":
        return kinmo + ["predict", str(partnet), "-o", str(out), *j, "-q"]
    if stage == "predict-no-ranges":
        return kinmo + ["predict", str(partnet), "-o", str(out), "--model", str(_bundle_without_ranges(out.parent)),
                        *j, "-q"]
    if stage == "render":
        return kinmo + ["render", str(mobility), "-o", str(out), *j, "-q"]
    raise SystemExit(f"unknown stage {stage}")


def _bundle_without_ranges(folder: Path) -> Path:
    """A copy of the pretrained bundle in ``folder`` without its range prior."""
    import json

    from kinmo.pretrained import default_model

    dst = folder / "bundle-without-ranges"
    shutil.copytree(default_model(), dst)
    doc = json.loads((dst / "bundle.json").read_text())
    doc.pop("ranges", None)
    (dst / "ranges.json").unlink(missing_ok=True)
    (dst / "bundle.json").write_text(json.dumps(doc, indent=2))
    return dst


def _count(stage: str, partnet: Path, mobility: Path) -> int:
    from kinmo.data.readers import find_shapes

    return len(find_shapes(mobility if stage == "render" else partnet))


def run_stage(stage: str, partnet: Path, mobility: Path, jobs: int = 2, against: Path | None = None) -> dict:
    """One cold run of ``stage`` with ``-j jobs``: its row (module docstring); with
    ``against``, of the kinmo package in that folder (``PYTHONPATH``)."""
    n = _count(stage, partnet, mobility)
    with tempfile.TemporaryDirectory(prefix=f"kinmo-throughput-{stage}-") as tmp:
        env = dict(os.environ, KINMO_VHACD_CACHE=str(Path(tmp) / "collision-cache"))
        if against is not None:
            env["PYTHONPATH"] = os.pathsep.join([str(against.resolve()), *filter(None, [env.get("PYTHONPATH")])])
        load0 = os.getloadavg()[0]
        c0, t0 = _children_cpu(), time.perf_counter()
        r = subprocess.run(_command(stage, partnet, mobility, Path(tmp) / "out", jobs), env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
        load1 = os.getloadavg()[0]
        if r.returncode not in (0, 1):  # 1: some shapes failed (reported), the rest done
            raise SystemExit(f"{stage} failed ({r.returncode}):\n{r.stdout[-2000:]}")
        shutil.rmtree(Path(tmp) / "out", ignore_errors=True)
    return dict(stage=stage, jobs=jobs, kinmo="this" if against is None else str(against), shapes=n,
                wall_s=round(wall, 2), shapes_per_s=round(n / wall, 3), cpu_s_per_shape=round(cpu / n, 4),
                load_before=round(load0, 2), load_after=round(load1, 2), exit_code=r.returncode)


def against_lines(rows: list[dict]) -> list[str]:
    """Markdown rows of this kinmo's time against the other's (``--against``), per stage and
    ``-j``: the medians of both, their ratio, and the median of the ratios of the runs made
    side by side (the i-th run of each)."""
    out = []
    for stage, jobs in dict.fromkeys((r["stage"], r["jobs"]) for r in rows):
        mine = [r for r in rows if (r["stage"], r["jobs"], r["kinmo"]) == (stage, jobs, "this")]
        other = [r for r in rows if (r["stage"], r["jobs"]) == (stage, jobs) and r["kinmo"] != "this"]
        if not mine or not other:
            continue
        cells = []
        for key in ("wall_s", "cpu_s_per_shape"):
            a, b = statistics.median(r[key] for r in mine), statistics.median(r[key] for r in other)
            paired = statistics.median(x[key] / y[key] for x, y in zip(mine, other))
            cells.append(f"{b:.3f} -> {a:.3f} ({a / b - 1:+.1%}; paired {paired - 1:+.1%})")
        out.append(f"| {stage} | {jobs} | {len(mine)} | {cells[0]} | {cells[1]} |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--partnet", type=Path, default=SHARED / "partnet")
    ap.add_argument("--mobility", type=Path, default=SHARED / "partnet-mobility")
    ap.add_argument("--stages", default="pseudo-label,predict,render")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--jobs", default="2",
                    help="comma-separated -j values, e.g. 1,2: each stage runs at each, "
                         "alternating within a repeat, and the table gives the speed-up "
                         "over the first")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--against", type=Path, default=None,
                    help="the python/ folder of another kinmo checkout (Rust core built in place): "
                         "each run is followed by the same run of that kinmo, and the table gives "
                         "this one's time against it")
    args = ap.parse_args()
    jobs = [int(j) for j in args.jobs.split(",")]
    stages = args.stages.split(",")
    if args.against is not None:
        if not (args.against / "kinmo" / "__init__.py").is_file():
            raise SystemExit(f"--against {args.against}: no kinmo package there (give a checkout's python/ folder)")
        if "predict-no-ranges" in stages:
            raise SystemExit("--against: predict-no-ranges copies this kinmo's bundle; leave it out")
    kinmos = [None] if args.against is None else [None, args.against]
    rows = []
    for k in range(args.repeats):  # stages alternate within a repeat: load drifts hit them alike
        for stage in stages:
            for j in jobs:
                for other in kinmos:
                    row = run_stage(stage, args.partnet, args.mobility, j, other)
                    print(f"{stage} -j {j} #{k + 1}: {row}", file=sys.stderr, flush=True)
                    rows.append(row)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("| stage | -j | shapes | runs | wall s (median) | shapes/s | vs first -j | "
          "CPU s per shape | load before / after |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
    for stage in dict.fromkeys(r["stage"] for r in rows):
        base = None
        for j in jobs:
            rs = [r for r in rows if r["stage"] == stage and r["jobs"] == j and r["kinmo"] == "this"]
            med = lambda k: statistics.median(r[k] for r in rs)  # noqa: E731, B023
            base = base or med("wall_s")
            loads = ", ".join(f"{r['load_before']:.2f} / {r['load_after']:.2f}" for r in rs)
            print(f"| {stage} | {j} | {rs[0]['shapes']} | {len(rs)} | {med('wall_s'):.1f} | "
                  f"{med('shapes_per_s'):.2f} | {base / med('wall_s'):.2f}x | "
                  f"{med('cpu_s_per_shape'):.3f} | {loads} |")
    if args.against is not None:
        print(f"\nThis kinmo against {args.against} (alternating runs; before -> after, medians):\n")
        print("| stage | -j | runs | wall s | CPU s per shape |")
        print("|---|---:|---:|---|---|")
        print("\n".join(against_lines(rows)))
    print(f"\nrows: {args.out}")


if __name__ == "__main__":
    main()
