"""Benchmark of the motion GNN's training and inference steps (quick preset, CPU).

Every result is a ratio against a baseline measured in the same run (the machine is shared:
absolute times drift, ratios stay meaningful); the absolute medians are recorded too.

Measurements (median of ``--repeats`` passes over the same batches of real part graphs):

- ``threads``: a training epoch (forward + backward + Adam step) with 2 torch threads vs 1
  (why the quick preset uses one thread: the matrices are small);
- ``candidates``: the candidate direction head vs plain regression (its cost);
- ``inference``: inference (``torch.no_grad``, forward only) vs a training epoch;
- ``shapes``: shape-balanced vs edge-balanced loss (should be ~1: weighting is free).

Usage::

    python bench/bench_gnn.py [--cache /tmp/kinmo-cache/partnet-mobility] [--repeats 3]

Writes ``bench/results/gnn.csv``.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import time
from pathlib import Path

import torch

from kinmo.features import SemanticVocab, collate, graph_tensors
from kinmo.models import MotionGNN
from kinmo.models.losses import MotionLoss
from kinmo.train.config import preset
from kinmo.train.gnn import load_cache


def _batches(cache: Path, n_points: int, batch_size: int):
    graphs = [g for g in load_cache(cache) if g.has_labels]
    vocab = SemanticVocab.from_graphs(graphs)
    ts = [graph_tensors(g, vocab) for g in graphs]
    return vocab, [collate(ts[k:k + batch_size], n_points=n_points)
                   for k in range(0, len(ts), batch_size)], len(ts)


def _epoch(model, loss_fn, batches, train: bool) -> float:
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    t0 = time.perf_counter()
    for b in batches:
        if train:
            out = model(b)
            opt.zero_grad()
            loss_fn(out, b).total.backward()
            opt.step()
        else:
            with torch.no_grad():
                model(b)
    return time.perf_counter() - t0


def _median(fn, repeats: int) -> float:
    fn()  # warm-up
    return statistics.median(fn() for _ in range(repeats))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cache", type=Path, default=Path("/tmp/kinmo-cache/partnet-mobility"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "gnn.csv")
    args = ap.parse_args()
    cfg = preset("quick")
    vocab, batches, n = _batches(args.cache, cfg.n_points or 1024, cfg.batch_size)

    def model(**over):
        torch.manual_seed(0)
        mc = cfg.model.model_copy(update={"vocab_size": len(vocab), **over})
        return MotionGNN(mc)

    rows = []

    def record(name, base_name, t, t_base):
        rows.append({"measure": name, "baseline": base_name, "seconds": round(t, 4),
                     "baseline_seconds": round(t_base, 4), "ratio": round(t / t_base, 3),
                     "shapes": n})
        print(f"{name:>28} {t:8.3f} s  vs {base_name:<24} {t_base:8.3f} s  ratio {t / t_base:6.3f}")

    loss = MotionLoss("fine", balance="shapes")
    torch.set_num_threads(1)
    m = model()
    t1 = _median(lambda: _epoch(m, loss, batches, True), args.repeats)
    torch.set_num_threads(2)
    t2 = _median(lambda: _epoch(m, loss, batches, True), args.repeats)
    record("train epoch, 2 threads", "train epoch, 1 thread", t2, t1)
    torch.set_num_threads(1)
    mr = model(axis_mode="regress")
    tr = _median(lambda: _epoch(mr, loss, batches, True), args.repeats)
    record("train epoch, candidates", "train epoch, regress", t1, tr)
    ti = _median(lambda: _epoch(m, loss, batches, False), args.repeats)
    record("inference pass", "train epoch", ti, t1)
    le = MotionLoss("fine", balance="edges")
    te = _median(lambda: _epoch(m, le, batches, True), args.repeats)
    record("train epoch, shape-balanced", "train epoch, edge-balanced", t1, te)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
