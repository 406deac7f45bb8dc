"""Benchmark the peak memory of ``kinmo predict`` on a flat asset with many parts (issue 21,
finding 4).

A GLB scene of N random boxes (one node per box) has N (N - 1) directed sibling edges: 249,500
at N = 500. The motion GNN's per-edge heads (the axis-candidate head's input is
``(E, 10, 2H + D + 10)`` float32) and ``edges.json`` grow with them. This runs, each in a fresh
process so that its peak RSS is its own (``ru_maxrss`` of the child):

- **kinmo**: ``kinmo predict FILE`` as shipped (heads in chunks of
  :data:`kinmo.models.edge_gnn.EDGE_CHUNK` edges at inference, ``edges.json`` streamed);
- **unchunked**: the same with ``EDGE_CHUNK`` set past the edge count (the heads over every
  edge at once, as before the change; ``edges.json`` is streamed in both).

Peak RSS in GB and wall seconds per run are the medians over ``--repeats`` runs; the ratio is
kinmo / unchunked.

Usage::

    python bench/bench_predict_memory.py --model RUN_OR_BUNDLE [--parts 500] [--repeats 1]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

RUN = ("import sys, kinmo.models.edge_gnn as m; m.EDGE_CHUNK = int(sys.argv[1]); "
       "from kinmo.cli import app; sys.argv = ['kinmo'] + sys.argv[2:]; app()")


def boxes_glb(path: Path, n: int, seed: int = 0) -> Path:
    """A GLB scene of ``n`` random axis-aligned boxes, one node each."""
    rng = np.random.default_rng(seed)
    scene = trimesh.Scene()
    for k in range(n):
        b = trimesh.creation.box(extents=rng.uniform(0.02, 0.1, 3))
        b.apply_translation(rng.uniform(-1.0, 1.0, 3))
        scene.add_geometry(b, node_name=f"box{k}", geom_name=f"box{k}")
    path.write_bytes(scene.export(file_type="glb"))
    return path


def peak(chunk: int, glb: Path, model: str, out: Path) -> tuple[float, float]:
    """(peak RSS in GB, wall seconds) of one ``kinmo predict`` in a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", RUN, str(chunk), "predict", str(glb), "--model", model,
                    "--out", str(out), "--device", "cpu", "-q", "--format", "mobility_v2"],
                   check=True, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    # ru_maxrss of children is the largest child so far: run the larger variant last
    return max(after, before) / 1e6, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True)
    ap.add_argument("--parts", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=1)
    a = ap.parse_args()
    from kinmo.models.edge_gnn import EDGE_CHUNK

    with tempfile.TemporaryDirectory() as tmp:
        glb = boxes_glb(Path(tmp) / f"boxes{a.parts}.glb", a.parts)
        res: dict[str, list[tuple[float, float]]] = {"kinmo": [], "unchunked": []}
        # kinmo first: RUSAGE_CHILDREN keeps the maximum over children
        for name, chunk in (("kinmo", EDGE_CHUNK), ("unchunked", 10**12)):
            for r in range(a.repeats):
                res[name].append(peak(chunk, glb, a.model, Path(tmp) / f"out_{name}_{r}"))
    med = {k: (statistics.median(x[0] for x in v), statistics.median(x[1] for x in v)) for k, v in res.items()}
    edges = a.parts * (a.parts - 1)
    print(f"{a.parts} parts, {edges} sibling edges, median of {a.repeats} run(s)")
    print("| variant | peak RSS (GB) | wall (s) |")
    print("|---|---|---|")
    for k, (gb, s) in med.items():
        print(f"| {k} | {gb:.2f} | {s:.1f} |")
    print(f"ratio kinmo / unchunked: peak RSS {med['kinmo'][0] / med['unchunked'][0]:.2f}")


if __name__ == "__main__":
    main()
