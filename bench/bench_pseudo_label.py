"""Throughput of ``kinmo pseudo-label`` (issue 11 item 5), learned selector vs the paper's.

Measures :func:`kinmo.pseudo_label.pseudo_label_dataset` on a PartNet dataset (or its first
``--limit`` shapes):

- **in process** (``-j 1``, this process): shapes/s, CPU-s per shape and a per-stage
  breakdown (exclusive CPU time of each stage: part graph from the cache or built, shape
  folder read, GNN inference, candidate generation, mesh loading, candidate features
  outside the sweep, swept collision / line-to-mesh distance (parry), axis network, mobility
  tree, writing, other), for the learned selector (``selector="ranker"``, the default) and,
  as the same-run baseline, the paper's selector (axis network + 0.5/0.3/0.2 weights)
  (``--axis-model``; without one an untrained network of the ``quick`` preset, whose cost is
  the same and whose kept count means nothing);
- **with worker processes** (``-j N``): wall shapes/s and the CPU seconds of the children.

CPU time is the fair number on the shared machine: on an idle machine with ``N`` cores the
throughput is about ``N / (CPU-s per shape)`` (an extrapolation, printed as such).

Usage::

    python bench/bench_pseudo_label.py --data /work/shared/data/partnet --model GNN_RUN \\
        --ranker RANKER_DIR [--axis-model AXIS_RUN] [--cache CACHE] [--limit N] [-j 2]
        [--profile OUT.prof]

Prints a table and writes ``bench/results/pseudo_label.csv``.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import csv
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "pseudo_label.csv"

#: (stage, module, attribute) wrapped by the exclusive stage timer
STAGES = [
    ("graph", "kinmo.data.build", "build_graph"),
    ("graph", "kinmo.data.graph", "PartGraph.load"),
    ("read_shape", "kinmo.data.readers", "read_shape"),
    ("gnn", "kinmo.predict", "infer_edges_with_priors"),
    ("gnn", "kinmo.predict", "infer_edges"),
    ("candidates", "kinmo.refine.selector", "edge_candidates"),
    ("candidates", "kinmo.refine.candidates", "edge_candidates"),
    ("meshes", "kinmo.refine.selector", "shape_meshes"),
    ("features", "kinmo.refine.selector", "candidate_features"),
    ("sweep", "kinmo.geometry", "sweep_collisions"),
    ("sweep", "kinmo.geometry", "SweepObstacle.__init__"),
    ("sweep", "kinmo.geometry", "SweepObstacle.sweep"),
    ("sweep", "kinmo.geometry", "line_mesh_distance"),
    ("axis_net", "kinmo.refine.refine", "_network_feasibility"),
    ("tree", "kinmo.mobility_tree", "build_mobility_tree"),
    ("write", "kinmo.pseudo_label", "_write_folder"),
    ("write", "kinmo.pseudo_label", "write_json"),
]


class StageTimer:
    """Exclusive CPU time per stage: a nested stage's time is not counted in its caller's."""

    def __init__(self) -> None:
        self.cpu: dict[str, float] = {}
        self.stack: list[list] = []  # [stage, start, child time]
        self._undo: list = []

    def wrap(self, stage: str, fn):
        def timed(*a, **k):
            self.stack.append([stage, time.process_time(), 0.0])
            try:
                return fn(*a, **k)
            finally:
                st, t0, child = self.stack.pop()
                dt = time.process_time() - t0
                self.cpu[st] = self.cpu.get(st, 0.0) + dt - child
                if self.stack:
                    self.stack[-1][2] += dt
        timed.__wrapped__ = fn
        return timed

    def install(self) -> None:
        import importlib

        for stage, mod, attr in STAGES:
            try:
                m = importlib.import_module(mod)
            except ImportError:
                continue
            owner, name = m, attr
            if "." in attr:
                cls, name = attr.split(".")
                owner = getattr(m, cls, None)
            if owner is None or not hasattr(owner, name):
                continue
            orig = owner.__dict__[name] if isinstance(owner, type) else getattr(owner, name)
            if isinstance(orig, classmethod):
                new = classmethod(self.wrap(stage, orig.__func__))
            elif isinstance(orig, staticmethod):
                new = staticmethod(self.wrap(stage, orig.__func__))
            else:
                new = self.wrap(stage, orig)
            setattr(owner, name, new)
            self._undo.append((owner, name, orig))

    def uninstall(self) -> None:
        for owner, name, orig in reversed(self._undo):
            setattr(owner, name, orig)
        self._undo.clear()


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def subset(data: Path, limit: int, tmp: Path) -> Path:
    """A folder of symbolic links to the first ``limit`` shape folders of ``data``."""
    from kinmo.data.readers import find_shapes

    folders = find_shapes(data)
    if not limit or limit >= len(folders):
        return data
    root = tmp / "data"
    root.mkdir()
    for f in folders[:limit]:
        os.symlink(f, root / f.name)
    return root


def run(data, model, axis, out, config, workers, cache, timer=None, profile=None):
    from kinmo.pseudo_label import pseudo_label_dataset

    c0, w0, k0 = time.process_time(), time.perf_counter(), children_cpu()
    prof = cProfile.Profile() if profile else None
    if timer:
        timer.install()
    try:
        with (prof if prof else contextlib.nullcontext()):
            res = pseudo_label_dataset(data, model, axis, out, config, workers=workers,
                                       cache=cache, force=True, progress=False)
    finally:
        if timer:
            timer.uninstall()
    if prof:
        prof.dump_stats(profile)
    wall = time.perf_counter() - w0
    cpu = time.process_time() - c0 + children_cpu() - k0
    return res, wall, cpu


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--model", type=Path, required=True, help="fine GNN run")
    ap.add_argument("--ranker", type=Path, required=True, help="folder with ranker.json")
    ap.add_argument("--axis-model", type=Path, help="axis network run of the paper baseline "
                    "(default: an untrained quick-preset one; its kept count is meaningless)")
    ap.add_argument("--cache", type=Path)
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("-j", "--workers", type=int, default=2)
    ap.add_argument("--profile", type=Path, help="cProfile output of the in-process ranker run")
    args = ap.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    from kinmo.pseudo_label import PseudoLabelConfig
    from kinmo.refine.refine import RefineConfig

    ranker_cfg = PseudoLabelConfig(refine=RefineConfig(
        selector="ranker", ranker=str(args.ranker / "ranker.json")))
    paper_cfg = PseudoLabelConfig()
    rows = []
    with tempfile.TemporaryDirectory(prefix="kinmo-bench-pl-") as tmp:
        tmp = Path(tmp)
        data = subset(args.data, args.limit, tmp)
        axis = args.axis_model
        if axis is None:  # an untrained quick-preset network: same cost, meaningless scores
            from kinmo.refine.axis_net import AxisSelectionNet
            from kinmo.refine.train import preset_config, save_axis_model

            axis = tmp / "axis"
            axis.mkdir()
            save_axis_model(axis / "model.pt", AxisSelectionNet(preset_config("quick").net))
        runs = [("ranker", args.ranker, ranker_cfg), ("paper", axis, paper_cfg)]
        for name, axis, cfg in runs:
            timer = StageTimer()
            res, wall, cpu = run(data, args.model, axis, tmp / f"out_{name}", cfg, -1,
                                 args.cache, timer, args.profile if name == "ranker" else None)
            n = len(res.records)
            kept = res.count("kept")
            stages = dict(sorted(timer.cpu.items(), key=lambda kv: -kv[1]))
            stages["other"] = cpu - sum(timer.cpu.values())
            rows.append({"selector": name, "workers": 1, "shapes": n, "kept": kept,
                         "wall_s": wall, "cpu_s": cpu, "shapes_per_s": n / wall,
                         "cpu_s_per_shape": cpu / n, "idle_2core_shapes_per_s": 2 * n / cpu,
                         **{f"stage_{k}_ms": 1000 * v / n for k, v in stages.items()}})
            if args.workers > 1:
                res, wall, cpu = run(data, args.model, axis, tmp / f"out_{name}_j", cfg,
                                     args.workers, args.cache)
                rows.append({"selector": name, "workers": args.workers, "shapes": n,
                             "kept": res.count("kept"), "wall_s": wall, "cpu_s": cpu,
                             "shapes_per_s": n / wall, "cpu_s_per_shape": cpu / n,
                             "idle_2core_shapes_per_s": 2 * n / cpu})
    print(f"load average {os.getloadavg()[0]:.1f}; CPU includes worker processes")
    for r in rows:
        print(f"{r['selector']:7s} -j {r['workers']}: {r['shapes']} shapes ({r['kept']} kept) "
              f"{r['wall_s']:.1f} s wall, {r['shapes_per_s']:.2f} shapes/s, "
              f"{r['cpu_s_per_shape'] * 1000:.0f} CPU-ms/shape -> idle 2 cores "
              f"~{r['idle_2core_shapes_per_s']:.1f} shapes/s (extrapolated)")
        st = {k[6:-3]: v for k, v in r.items() if k.startswith("stage_")}
        if st:
            print("    per shape (CPU ms): " + ", ".join(f"{k} {v:.1f}" for k, v in st.items()))
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(RESULTS, "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
