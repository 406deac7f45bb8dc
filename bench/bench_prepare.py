"""Benchmark ``kinmo prepare`` against the same work done with trimesh + python-fcl.

Both sides process every shape folder of a dataset (default: ``partnet-mobility/`` of the
shared data) with the same number of worker processes and write one ``.npz`` per shape:

- **kinmo**: :func:`kinmo.prepare.prepare_dataset` (Rust core: OBJ loading, sampling, OBBs,
  contact/distances), ``force=True`` so nothing is skipped;
- **baseline**: per shape, ``trimesh.load`` of every OBJ, per node
  ``trimesh.sample.sample_surface`` of the union of its meshes and
  ``trimesh.bounds.oriented_bounds`` of its vertices, contact as python-fcl distances
  between every pair of leaf meshes whose bounding boxes (grown by the distance cap) overlap.

Each side runs in its own subprocess, which reports its wall time, the per-shape seconds,
CPU seconds (user + system, all processes: the fair measure on a loaded shared machine) and
peak resident memory (``resource.getrusage``: the process itself and the largest of its
worker processes). The table gives ratios against the same-run baseline: wall time, CPU
time and median per-shape time (target >= 10x), and peak memory (target < 2 GB).

``--stages`` instead times the three Rust stages of ``kinmo prepare`` one shape at a time
(one process, one rayon thread unless ``RAYON_NUM_THREADS`` says otherwise): it runs
:func:`kinmo.prepare.prepare_dataset` with ``workers=1`` and wraps the ``load_objs``,
``fit_obb_batch`` and ``contact_pairs`` that :mod:`kinmo.data.build` calls, so each stage
sees exactly the inputs of a real run. On the same inputs, in the same run, it times

- **load**: ``trimesh.load(path, force="mesh", process=False)`` of every file, and a plain
  read of the same bytes (``Path.read_bytes``, page cache warm: the files were just read):
  the *parse limit*; kinmo's load throughput should be >= 50% of the plain read's;
- **OBB**: ``trimesh.bounds.oriented_bounds`` of every point set (scipy's Qhull inside);
- **contacts**: python-fcl ``distance`` between every pair of meshes whose boxes, grown by
  the tolerance, overlap (BVHs built once per mesh).

and prints per-stage medians over shapes (kinmo, baseline, ratio) and the total per shape.

``--parsers`` builds and runs the Rust example ``obj_parsers`` of ``kinmo-geometry`` on every
OBJ file of ``--data``: one thread, median MB/s over ``--repeat`` passes of a plain read,
kinmo's ``load_obj`` (tobj), tobj alone, and the maintained crates ``obj`` and
``mesh-loader`` (each with the vertex count it returns: one that de-indexes the faces returns
more vertices than kinmo's mesh has), all in the same run.

Usage::

    python bench/bench_prepare.py [--data DIR] [--workers N] [--n-points 1024] [--limit K]
    python bench/bench_prepare.py --stages [--data DIR] [--limit K] [--repeat R]
    python bench/bench_prepare.py --parsers [--data DIR] [--repeat R]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------------ baseline


def baseline_one(args: tuple[str, str, int, int, float, float]) -> float:
    """The trimesh + python-fcl version of one shape; returns its seconds."""
    import fcl
    import numpy as np
    import trimesh

    from kinmo.data.readers import read_shape

    folder, out, n_points, seed, tol_rel, cap_rel = args
    t0 = time.perf_counter()
    shape = read_shape(folder)
    h = shape.hierarchy
    order = h.order
    names = list(dict.fromkeys(o for n in order for o in h.nodes[n].objs))
    meshes = {n: trimesh.load(shape.mesh_path(n), force="mesh") for n in names}
    allv = np.concatenate([m.vertices for m in meshes.values()])
    diag = float(np.linalg.norm(allv.max(0) - allv.min(0)))
    cap, tol = cap_rel * diag, tol_rel * diag

    points, boxes = [], []
    for k, nid in enumerate(order):
        m = trimesh.util.concatenate([meshes[o] for o in h.mesh_names(nid)])
        p, _ = trimesh.sample.sample_surface(m, n_points, seed=seed + k)
        points.append(np.asarray(p, np.float32))
        to_origin, extents = trimesh.bounds.oriented_bounds(m.vertices)
        boxes.append((to_origin, extents))

    leaves = [n for n in order if h.nodes[n].is_leaf]
    leaf_mesh = {n: trimesh.util.concatenate([meshes[o] for o in h.nodes[n].objs]) for n in leaves}
    objs, lo, hi = {}, {}, {}
    for n, m in leaf_mesh.items():
        bvh = fcl.BVHModel()
        bvh.beginModel(len(m.vertices), len(m.faces))
        bvh.addSubModel(np.asarray(m.vertices, float), np.asarray(m.faces, np.int32))
        bvh.endModel()
        objs[n] = fcl.CollisionObject(bvh, fcl.Transform())
        lo[n], hi[n] = m.bounds[0] - cap, m.bounds[1] + cap
    dist = {}
    for i, a in enumerate(leaves):
        for b in leaves[i + 1 :]:
            if (lo[a] <= hi[b]).all() and (lo[b] <= hi[a]).all():
                d = fcl.distance(objs[a], objs[b], fcl.DistanceRequest(), fcl.DistanceResult())
                if d <= cap:
                    dist[(a, b)] = dist[(b, a)] = max(d, 0.0)
    sib = []
    for nid in order:
        kids = h.nodes[nid].children
        for a in kids:
            for b in kids:
                if a != b:
                    la, lb = h.leaves(a), h.leaves(b)
                    d = min((dist.get((x, y), cap) for x in la for y in lb), default=cap)
                    sib.append((a, b, d, d <= tol))
    np.savez_compressed(
        Path(out) / f"{shape.id}.npz",
        points=np.stack(points),
        obb=np.stack([b[0] for b in boxes]),
        extents=np.stack([b[1] for b in boxes]),
        sibling=np.asarray(sib, dtype=float).reshape(-1, 4),
    )
    return time.perf_counter() - t0


def run_baseline(data: str, workers: int, n_points: int, seed: int) -> dict:
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    from kinmo.data.readers import find_shapes

    folders = [str(f) for f in find_shapes(data)]
    with tempfile.TemporaryDirectory() as out:
        jobs = [(f, out, n_points, seed, 0.01, 0.1) for f in folders]
        t0 = time.perf_counter()
        if workers == 1:
            secs = [baseline_one(j) for j in jobs]
        else:
            with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as ex:
                secs = list(ex.map(baseline_one, jobs))
        wall = time.perf_counter() - t0
    return {"wall": wall, "per_shape": dict(zip(folders, secs)), "n": len(folders)}


def run_kinmo(data: str, workers: int, n_points: int, seed: int) -> dict:
    from kinmo.prepare import PrepareConfig, prepare_dataset

    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        res = prepare_dataset(
            data, out, PrepareConfig(n_points=n_points, seed=seed), workers=workers,
            force=True, progress=False,
        )
        wall = time.perf_counter() - t0
    failed = [r.error for r in res.failures]
    return {
        "wall": wall,
        "per_shape": {r.source: r.seconds for r in res.rows},
        "n": res.n_shapes,
        "failed": failed,
    }


# ------------------------------------------------------------------------------ stages


def _median_ms(xs: list[float]) -> float:
    import numpy as np

    return 1e3 * float(np.median(xs)) if xs else float("nan")


def run_stages(data: str, n_points: int, seed: int, limit: int, repeat: int) -> dict:
    """Per-shape seconds of each prepare stage, kinmo and baseline, on the same inputs."""
    import fcl
    import numpy as np
    import trimesh

    import kinmo.data.build as build
    from kinmo.data.readers import find_shapes
    from kinmo.prepare import PrepareConfig, prepare_dataset

    folders = [str(f) for f in find_shapes(data)][: limit or None]
    cur: dict[str, float] = {}
    rows: list[dict[str, float]] = []
    orig = {n: getattr(build, n) for n in ("load_objs", "fit_obb_batch", "contact_pairs")}

    def best_of(fn, *args):
        t = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = fn(*args)
            t.append(time.perf_counter() - t0)
        cur["spent"] = cur.get("spent", 0.0) + sum(t)  # all timed work, baselines included
        return out, min(t)

    def load_objs(paths):
        out, cur["load"] = best_of(orig["load_objs"], paths)
        _, cur["read"] = best_of(lambda: [Path(p).read_bytes() for p in paths])
        cur["bytes"] = float(sum(os.path.getsize(p) for p in paths))
        _, cur["load_base"] = best_of(
            lambda: [trimesh.load(str(p), force="mesh", process=False) for p in paths])
        return out

    def fit_obb_batch(sets, *a, **k):
        out, cur["obb"] = best_of(orig["fit_obb_batch"], sets, *a, **k)
        _, cur["obb_base"] = best_of(
            lambda: [trimesh.bounds.oriented_bounds(np.asarray(v)) for v in sets])
        return out

    def contact_pairs(meshes, tol):
        out, cur["contact"] = best_of(orig["contact_pairs"], meshes, tol)

        def fcl_pairs():
            objs, lo, hi = [], [], []
            for v, f in meshes:
                m = fcl.BVHModel()
                m.beginModel(len(v), len(f))
                m.addSubModel(np.asarray(v, float), np.asarray(f, np.int32))
                m.endModel()
                objs.append(fcl.CollisionObject(m, fcl.Transform()))
                lo.append(v.min(0) - tol)
                hi.append(v.max(0) + tol)
            for i in range(len(objs)):
                for j in range(i + 1, len(objs)):
                    if (lo[i] <= hi[j]).all() and (lo[j] <= hi[i]).all():
                        fcl.distance(objs[i], objs[j], fcl.DistanceRequest(),
                                     fcl.DistanceResult())

        _, cur["contact_base"] = best_of(fcl_pairs)
        return out

    def wrapped_build(*a, **k):
        cur.clear()
        t0 = time.perf_counter()
        out = orig_build(*a, **k)
        # build_graph as it runs alone: the timed work replaced by one kinmo run of each stage
        cur["total"] = time.perf_counter() - t0 - cur.pop("spent", 0.0) + sum(
            cur.get(x, 0.0) for x in ("load", "obb", "contact"))
        rows.append(dict(cur))
        return out

    import kinmo.prepare as prep

    orig_build = prep.build_graph
    for n, f in (("load_objs", load_objs), ("fit_obb_batch", fit_obb_batch),
                 ("contact_pairs", contact_pairs)):
        setattr(build, n, f)
    prep.build_graph = wrapped_build
    with tempfile.TemporaryDirectory() as out:
        for f in folders:
            prepare_dataset(f, out, PrepareConfig(n_points=n_points, seed=seed), workers=1,
                            force=True, progress=False)
    return {"rows": rows, "n": len(folders)}


def print_stages(res: dict, repeat: int) -> None:
    import numpy as np
    from rich.console import Console
    from rich.table import Table

    rows = res["rows"]
    col = lambda k: [r[k] for r in rows if k in r]  # noqa: E731
    t = Table(title=f"prepare stages: {len(rows)} shapes, 1 process, "
                    f"RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'all')}, "
                    f"best of {repeat} per shape, medians over shapes")
    for c in ("stage", "kinmo [ms]", "baseline [ms]", "baseline", "ratio"):
        t.add_column(c, justify="right")
    for name, k, b, what in (("load", "load", "load_base", "trimesh.load"),
                             ("OBB", "obb", "obb_base", "trimesh oriented_bounds"),
                             ("contacts", "contact", "contact_base", "python-fcl distance")):
        km, bm = _median_ms(col(k)), _median_ms(col(b))
        t.add_row(name, f"{km:.2f}", f"{bm:.2f}", what, f"{bm / km:.1f}x")
    t.add_row("plain read", f"{_median_ms(col('read')):.2f}", "", "read_bytes, warm cache", "")
    t.add_row("total build_graph", f"{_median_ms(col('total')):.2f}", "", "", "")
    Console().print(t)
    mb = np.array(col("bytes")) / 2**20
    load_tp = float(np.median(mb / np.array(col("load"))))
    read_tp = float(np.median(mb / np.array(col("read"))))
    print(f"throughput (median over shapes): load_objs {load_tp:.0f} MB/s, plain read "
          f"{read_tp:.0f} MB/s: parse limit {100 * load_tp / read_tp:.1f}% of plain read "
          f"(target >= 50%)")
    print("STAGES_JSON " + json.dumps({k: _median_ms(col(k)) for k in (
        "load", "load_base", "read", "obb", "obb_base", "contact", "contact_base", "total")}))


def _child(side: str, data: str, workers: int, n_points: int, seed: int) -> None:
    fn = run_kinmo if side == "kinmo" else run_baseline
    out = fn(data, workers, n_points, seed)
    kb = 1024 if sys.platform != "darwin" else 1  # ru_maxrss: KiB on Linux, bytes on macOS
    out["rss_self_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * kb / 2**20
    out["rss_child_mb"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * kb / 2**20
    # CPU seconds of the side and its workers: robust to other load on a shared machine.
    out["cpu_s"] = sum(
        u.ru_utime + u.ru_stime
        for u in (resource.getrusage(resource.RUSAGE_SELF),
                  resource.getrusage(resource.RUSAGE_CHILDREN))
    )
    print("BENCH_JSON " + json.dumps(out))


def _spawn(side: str, data: str, workers: int, n_points: int, seed: int) -> dict:
    cmd = [sys.executable, __file__, "--child", side, "--data", data, "--workers", str(workers),
           "--n-points", str(n_points), "--seed", str(seed)]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO / "python"), env.get("PYTHONPATH")]))
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(f"{side} failed:\n{p.stderr[-3000:]}")
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("BENCH_JSON "))
    return json.loads(line[len("BENCH_JSON "):])


def run_parsers(data: str, repeat: int) -> None:
    """Build and run ``examples/obj_parsers.rs`` on every OBJ file under ``data``."""
    files = sorted(str(p) for p in Path(data).rglob("*.obj"))
    if not files:
        raise SystemExit(f"{data}: no .obj file")
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "kinmo-geometry",
                    "--example", "obj_parsers"], cwd=REPO, check=True)
    exe = REPO / "target" / "release" / "examples" / "obj_parsers"
    # one argument per file: the 11,313 paths of the shared data are about 1 MB, under the
    # 2 MB that Linux allows for the arguments of a command
    subprocess.run([str(exe), "--repeat", str(repeat), *files], check=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(REPO.parent / "shared" / "data" / "partnet-mobility"))
    ap.add_argument("--workers", type=int, default=0, help="0: one per CPU")
    ap.add_argument("--n-points", type=int, default=1024)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--child", choices=["kinmo", "baseline"], help=argparse.SUPPRESS)
    ap.add_argument("--stages", action="store_true",
                    help="time the load / OBB / contact stages against trimesh, fcl, plain read")
    ap.add_argument("--parsers", action="store_true",
                    help="OBJ parse throughput: kinmo/tobj, obj, mesh-loader, plain read")
    ap.add_argument("--limit", type=int, default=0, help="--stages: first K shapes (0: all)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="--stages: best of R per shape; --parsers: median of R passes")
    a = ap.parse_args()
    if a.parsers:
        run_parsers(a.data, a.repeat)
        return
    if a.stages:
        print_stages(run_stages(a.data, a.n_points, a.seed, a.limit, a.repeat), a.repeat)
        return
    workers = a.workers or len(os.sched_getaffinity(0))
    if a.child:
        _child(a.child, a.data, workers, a.n_points, a.seed)
        return

    import numpy as np
    from rich.console import Console
    from rich.table import Table

    k = _spawn("kinmo", a.data, workers, a.n_points, a.seed)
    b = _spawn("baseline", a.data, workers, a.n_points, a.seed)
    common = sorted(set(k["per_shape"]) & set(b["per_shape"]))
    ratios = np.array([b["per_shape"][s] / max(k["per_shape"][s], 1e-9) for s in common])
    kmed = float(np.median([k["per_shape"][s] for s in common]))
    bmed = float(np.median([b["per_shape"][s] for s in common]))

    t = Table(title=f"prepare {Path(a.data).name}: {k['n']} shapes, {workers} workers, "
                    f"{a.n_points} points/node")
    for col in ("", "kinmo", "trimesh+fcl", "ratio"):
        t.add_column(col, justify="right")
    t.add_row("wall time [s]", f"{k['wall']:.1f}", f"{b['wall']:.1f}",
              f"{b['wall'] / k['wall']:.1f}x")
    t.add_row("CPU time, all processes [s]", f"{k['cpu_s']:.1f}", f"{b['cpu_s']:.1f}",
              f"{b['cpu_s'] / k['cpu_s']:.1f}x")
    t.add_row("median per shape [s]", f"{kmed:.3f}", f"{bmed:.3f}", f"{bmed / kmed:.1f}x")
    t.add_row("median of per-shape ratios", "", "", f"{np.median(ratios):.1f}x")
    t.add_row("peak RSS, main process [MB]", f"{k['rss_self_mb']:.0f}", f"{b['rss_self_mb']:.0f}", "")
    t.add_row("peak RSS, largest worker [MB]", f"{k['rss_child_mb']:.0f}",
              f"{b['rss_child_mb']:.0f}", "")
    bound_k = k["rss_self_mb"] + workers * k["rss_child_mb"]
    bound_b = b["rss_self_mb"] + workers * b["rss_child_mb"]
    t.add_row("peak RSS bound, all processes [MB]", f"{bound_k:.0f}", f"{bound_b:.0f}", "")
    Console().print(t)
    if k.get("failed"):
        Console().print(f"[red]{len(k['failed'])} shapes failed in kinmo:[/] {k['failed'][:3]}")
    verdict = "PASS" if b["wall"] / k["wall"] >= 10 and bound_k < 2048 else "MISS"
    print(f"targets (>= 10x wall time, < 2 GB): {verdict}")


if __name__ == "__main__":
    main()
