"""Benchmarks of the refinement stage (:mod:`kinmo.refine`) against same-run baselines.

Uses the harness of ``bench_geometry.py`` (medians of repeats; wall and CPU time; every
result a ratio against a baseline measured in the same run, because the machine is shared).

Sections (``--only NAME``):

- ``apply``: moving a part's points by C candidate motions: Rust
  :func:`kinmo.geometry.apply_motions` (parallel over motions, written straight into the
  output) vs the numpy equivalent (Rodrigues matrices + one ``einsum``), for the sizes the
  refinement uses (16 motions x 512 points) and larger ones.
- ``edgeconv``: the axis network's feasibility of a shape's candidate motions with kinmo's
  EdgeConv (``A x_j + B x_i``: per-point products, then a gather of the outputs) vs the
  textbook EdgeConv (gather ``[x_j - x_i, x_i]``, then a 1x1 convolution), same weights and
  the same outputs.
- ``batched``: the network side of the refinement on real objects: the feasibility of every
  candidate line of every labelled moving edge (its fine type's candidates, the paper's
  ``±30/45/60/80°``), scored by :func:`kinmo.refine.feasibility.score_lines` once per
  shape and once for all shapes together, against the per-edge loop the refinement used
  (one rest cloud and :meth:`~kinmo.refine.axis_net.AxisSelectionNet.feasibility` in chunks
  of 16 per edge, ``torch.no_grad``); candidate motions/s and shapes/s, max |diff| of the
  scores (same sampled points).
- ``shape``: refining every moving joint of real objects (candidates, interaction regions,
  motions, network, scores: :func:`kinmo.refine.refine.refine_predictions` with the labels as
  predictions), candidate motions scored per second, and the share of the time spent outside
  the network (geometry) against a run whose motions are applied with numpy.

Usage::

    python bench/bench_refine.py [--quick] [--only apply,edgeconv,batched,shape] [--cache DIR]
        [--axis-model RUN]

``--cache``: a ``kinmo prepare`` cache of PartNet-Mobility (built in a temporary folder from
the shared data when absent). ``--axis-model``: a trained network (default: an untrained one
of the ``quick`` preset; timing does not depend on the weights). Prints a table and writes
``bench/results/refine.csv``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))

from bench_geometry import Bench, measure  # noqa: E402

RESULTS = REPO / "bench" / "results" / "refine.csv"


def numpy_apply_motions(points, origins, directions, angles, translations):
    """The numpy equivalent of :func:`kinmo.geometry.apply_motions` (Rodrigues + einsum)."""
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    c, s = np.cos(angles), np.sin(angles)
    k = np.zeros((len(d), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -d[:, 2], d[:, 1], -d[:, 0]
    k = k - k.transpose(0, 2, 1)
    r = np.eye(3) + s[:, None, None] * k + (1 - c)[:, None, None] * (k @ k)
    t = origins - np.einsum("cij,cj->ci", r, origins) + translations[:, None] * d
    return np.einsum("cij,nj->cni", r, points) + t[:, None, :]


def bench_apply(bench: Bench) -> None:
    from kinmo.geometry import apply_motions

    rng = np.random.default_rng(0)
    for c, n in ((16, 512), (64, 1024), (256, 2048)):
        pts = rng.normal(size=(n, 3))
        o, d = rng.normal(size=(c, 3)), rng.normal(size=(c, 3))
        a, t = rng.uniform(-2, 2, c), rng.uniform(-1, 1, c)
        ref = numpy_apply_motions(pts, o, d, a, t)
        got = apply_motions(pts, o, d, a, t)
        err = float(np.abs(ref - got).max())
        reps = bench.reps(50 if c * n < 10**5 else 10, 3)
        args = (pts, o, d, a, t)
        row = bench.compare(
            "apply", f"apply_motions {c} x {n}", lambda args=args: apply_motions(*args),
            "numpy", lambda args=args: numpy_apply_motions(*args), reps,
            unit="max |diff|", value=err,
        )
        row.note = f"{c * n / row.wall_s / 1e6:.1f} M points/s"


def _naive_edgeconv_forward(self, x, idx=None):
    """Textbook EdgeConv with the same weights: gather [x_j - x_i, x_i], then the linear map."""
    import torch

    from kinmo.refine.axis_net import _gather, knn

    if idx is None:
        idx = knn(x, min(self.k, x.shape[1]))
    c = self.out_channels
    w = self.proj.weight  # rows: A (c), B (c); W [x_j - x_i, x_i] = A (x_j - x_i) + (A + B) x_i
    w1, w2 = w[:c], w[:c] + w[c:]
    nb = _gather(x, idx)  # (B, N, k, C_in)
    xi = x.unsqueeze(2).expand_as(nb)
    y = torch.cat([nb - xi, xi], dim=-1) @ torch.cat([w1, w2], dim=1).T
    if self.proj.bias is not None:
        y = y + self.proj.bias[:c] + self.proj.bias[c:]
    return self.act(self.norm(y)).max(dim=2).values


def _model(path: str | None):
    import torch

    from kinmo.refine.axis_net import AxisSelectionNet
    from kinmo.refine.train import load_axis_model, preset_config

    if path:
        return load_axis_model(path)
    torch.manual_seed(0)
    return AxisSelectionNet(preset_config("quick").net).eval()


def bench_edgeconv(bench: Bench) -> None:
    import torch

    from kinmo.refine.axis_net import EdgeConv

    model = _model(bench.axis_model)
    n = model.config.n_points
    rng = torch.Generator().manual_seed(0)
    before = torch.randn(n, 4, generator=rng)
    after = torch.randn(16, n, 4, generator=rng)
    fast = model.feasibility(before, after)
    orig = EdgeConv.forward
    try:
        EdgeConv.forward = _naive_edgeconv_forward
        slow = model.feasibility(before, after)
        naive = measure(lambda: model.feasibility(before, after), bench.reps(5, 2))
    finally:
        EdgeConv.forward = orig
    err = float((fast - slow).abs().max())
    bench.compare("edgeconv", f"feasibility of 16 motions x {n} points",
                  lambda: model.feasibility(before, after), "textbook EdgeConv", naive,
                  bench.reps(5, 2), unit="max |diff|", value=err)


def _cache(bench: Bench) -> Path:
    if bench.cache:
        return Path(bench.cache)
    from kinmo.prepare import prepare_dataset

    tmp = Path(tempfile.mkdtemp(prefix="kinmo-bench-refine-"))
    prepare_dataset(bench.data / "partnet-mobility", tmp, workers=1, progress=False)
    return tmp


def bench_shape(bench: Bench) -> None:
    import torch

    from kinmo.refine.refine import refine_predictions
    from kinmo.refine.train import load_graphs, moving_edges

    torch.set_num_threads(1)
    model = _model(bench.axis_model)
    graphs = load_graphs(_cache(bench))
    # the objects with the most moving joints (cabinets, ovens, ...): the refinement's load
    ranked = sorted(graphs, key=lambda g: -len(moving_edges([g])))
    picked = [g for g in ranked if len(moving_edges([g])) <= 20][: 2 if bench.quick else 6]
    preds = []
    for g in picked:
        e = len(g.sibling_edges)
        p = np.full((e, 10), 0.01)
        p[np.arange(e), g.edge_fine] = 0.91
        d = np.nan_to_num(g.edge_axis_direction, nan=0.0)
        d[~d.any(axis=1)] = [0.0, 1.0, 0.0]
        preds.append({"probs": p, "direction": d,
                      "origin": np.nan_to_num(g.edge_axis_origin, nan=0.0)})

    def run_all():
        n = 0
        for g, p in zip(picked, preds):
            out = refine_predictions(g, p, model)
            n += sum(2 * len(r.candidates) for r in out.details.values())
        return n

    n_motions = run_all()
    n_joints = sum(len(moving_edges([g])) for g in picked)
    import kinmo.geometry as geo  # network_inputs looks apply_motions up at every call

    rust = geo.apply_motions
    try:
        geo.apply_motions = lambda p, o, d, a=None, t=None: numpy_apply_motions(
            p, np.asarray(o, float), np.asarray(d, float),
            np.zeros(len(o)) if a is None else np.asarray(a, float),
            np.zeros(len(o)) if t is None else np.asarray(t, float))
        base = measure(run_all, bench.reps(3, 1))
    finally:
        geo.apply_motions = rust
    row = bench.compare("shape", f"refine {len(picked)} objects ({n_joints} joints)", run_all,
                        "numpy motions", base, bench.reps(3, 1), unit="motions/s")
    row.value = n_motions / row.wall_s
    row.note = (f"{n_joints / row.wall_s:.1f} joints/s, {len(picked) / row.wall_s:.2f} "
                f"objects/s, ids {','.join(g.shape_id for g in picked)}")
    # where the time goes: the network's share, timed inside the same refinement
    net_s = [0.0]
    feas = model.feasibility

    def timed(*a, **k):
        t1 = time.perf_counter()
        try:
            return feas(*a, **k)
        finally:
            net_s[0] += time.perf_counter() - t1

    model.feasibility = timed
    try:
        t0 = time.perf_counter()
        run_all()
        total = time.perf_counter() - t0
    finally:
        del model.feasibility
    bench.note("shape", f"network share of the refinement time {net_s[0] / total:.0%} "
                        f"(network {net_s[0]:.2f} s of {total:.2f} s, one thread)")


def bench_batched(bench: Bench) -> None:
    import torch

    from kinmo.refine.candidates import candidate_axes
    from kinmo.refine.feasibility import PAPER_ANGLES, LineRequest, score_lines
    from kinmo.refine.motions import MotionAmounts, candidate_motions, edge_cloud, network_inputs
    from kinmo.refine.train import load_graphs, moving_edges

    torch.set_num_threads(1)
    model = _model(bench.axis_model)
    graphs = load_graphs(_cache(bench))
    picked = graphs[:: max(1, len(graphs) // (8 if bench.quick else 24))]
    amounts = MotionAmounts(PAPER_ANGLES)
    per_shape: list[list[LineRequest]] = []
    for g in picked:
        reqs = []
        for k, me in enumerate(moving_edges([g])):
            obb = (g.obb_center[me.moving], g.obb_axes[me.moving], g.obb_half_extents[me.moving])
            c = candidate_axes(obb, me.fine_type, g.points[me.moving], g.points[me.reference])
            reqs.append(LineRequest(g, me.moving, me.reference, c, seed=(0, k)))
        per_shape.append(reqs)
    n_motions = sum(2 * len(r.candidates) * (len(amounts.angles_deg)
                                             if r.candidates.motion != "P" else 1)
                    for reqs in per_shape for r in reqs)

    def per_edge_loop(model=model):  # the refinement's path before score_lines
        out = []
        for reqs in per_shape:
            for r in reqs:
                g = r.graph
                obb = (g.obb_center[r.moving], g.obb_axes[r.moving], g.obb_half_extents[r.moving])
                mot = candidate_motions(r.candidates, obb, amounts)
                pair = edge_cloud(g, r.moving, r.reference, model.config,
                                  np.random.default_rng(r.seed))
                rest, moved = network_inputs(pair, mot.origins, mot.directions, mot.angles,
                                             mot.translations)
                out.append(model.feasibility(torch.from_numpy(rest), torch.from_numpy(moved),
                                             chunk=16).numpy())
        return out

    def per_shape_batched():
        return [lf for reqs in per_shape for lf in score_lines(model, reqs, amounts)]

    def all_shapes_batched():
        return score_lines(model, [r for reqs in per_shape for r in reqs], amounts)

    ref = np.concatenate(per_edge_loop())
    got = np.concatenate([lf.per_motion.reshape(-1) for lf in all_shapes_batched()])
    err = float(np.abs(ref - got).max())
    base = measure(per_edge_loop, bench.reps(3, 1))
    n_shapes = len(picked)
    for name, fn in (("score_lines per shape", per_shape_batched),
                     ("score_lines all shapes", all_shapes_batched)):
        row = bench.compare("batched", f"{name}: {n_shapes} objects, {n_motions} motions", fn,
                            "per-edge loop", base, bench.reps(3, 1), unit="motions/s")
        row.value = n_motions / row.wall_s
        row.note = (f"{n_shapes / row.wall_s:.2f} shapes/s (per-edge loop "
                    f"{n_motions / base.wall_s:.0f} motions/s, {n_shapes / base.wall_s:.2f} "
                    f"shapes/s); max |diff| {err:.1e}; {model.config.n_points} points")
    # before: the per-edge loop with the previous quick preset's 512-point network
    from kinmo.refine.axis_net import AxisSelectionNet
    from kinmo.refine.train import preset_config

    torch.manual_seed(0)
    old = AxisSelectionNet(preset_config("quick", net={"n_points": 512}).net).eval()
    old_t = measure(lambda: per_edge_loop(old), bench.reps(3, 1))
    row = bench.compare("batched", f"score_lines all shapes vs 512-point per-edge loop: "
                        f"{n_shapes} objects", all_shapes_batched, "per-edge loop, 512 points",
                        old_t, bench.reps(3, 1), unit="motions/s")
    row.value = n_motions / row.wall_s
    row.note = (f"{n_shapes / row.wall_s:.2f} shapes/s vs {n_shapes / old_t.wall_s:.2f} "
                f"shapes/s ({n_motions / old_t.wall_s:.0f} motions/s) before")


SECTIONS = {"apply": bench_apply, "edgeconv": bench_edgeconv, "batched": bench_batched,
            "shape": bench_shape}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats and objects")
    ap.add_argument("--only", default="", help="comma-separated sections: " + ",".join(SECTIONS))
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--cache", default=None, help="kinmo prepare cache of partnet-mobility")
    ap.add_argument("--axis-model", default=None, help="trained axis network (run folder)")
    args = ap.parse_args(argv)
    bench = Bench(quick=args.quick, data=args.data)
    bench.cache = args.cache  # type: ignore[attr-defined]
    bench.axis_model = args.axis_model  # type: ignore[attr-defined]
    names = [s for s in args.only.split(",") if s] or list(SECTIONS)
    for name in names:
        if name not in SECTIONS:
            ap.error(f"unknown section {name!r}")
        SECTIONS[name](bench)
    bench.report(RESULTS)
    return 0


if __name__ == "__main__":
    sys.exit(main())
