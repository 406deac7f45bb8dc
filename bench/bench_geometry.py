"""Benchmarks of the Rust geometry core (:mod:`kinmo._core`) against same-run baselines.

Every measurement is the median of repeats, and every result is a ratio against a baseline
measured in the same run (trimesh, numpy, a numpy memory copy), never an absolute target:
the machine is shared, so absolute times drift while ratios stay meaningful. Both wall time
and CPU time (``time.process_time``: all threads of this process; the fair measure on a
loaded machine, but parallel code spends *more* CPU than wall time) are recorded.

Sections (``--only NAME`` to run some, comma-separated):

- ``load``: every OBJ of ``partnet-mobility/``: :func:`kinmo.geometry.load_objs` (parallel)
  and :func:`~kinmo.geometry.load_obj` in a loop vs ``trimesh.load(force='mesh',
  process=False)`` per file.
- ``sampling``: 1024 points per part on every part: :func:`~kinmo.geometry.sample_surface`
  per part and :func:`~kinmo.geometry.sample_surface_groups` in one call vs
  ``trimesh.sample.sample_surface`` per part (open3d is not a dependency: noted instead).
- ``motion``: C candidate motions of N points: :func:`~kinmo.geometry.apply_motions` vs the
  numpy equivalent (``motion_transforms`` + matmul), and its written bytes per second as a
  fraction of the memory-copy bandwidth (a numpy copy of a large array).

- ``before-after``: with ``--old-core PATH`` (a copy of an older ``_core*.so``), contact
  adjacency, OBB, interaction region and sampling of today's build against that one in the
  same run, with output agreement checks, and contact adjacency against FCL.
- ``obb``: every leaf part of ``partnet-mobility/``: :func:`~kinmo.geometry.fit_obb` per part
  vs ``trimesh.bounds.oriented_bounds`` (median per-part times, their ratio), tightness
  against trimesh (fractions tighter / equal / looser, max volume ratio) and up alignment.

Other modules add their own sections with the :func:`section` decorator and
:meth:`Bench.compare` / :meth:`Bench.measure`.

Usage::

    python bench/bench_geometry.py [--quick] [--only load,sampling,motion] [--data DIR]

Prints a table and writes ``bench/results/geometry.csv`` (one row per measurement).
"""

from __future__ import annotations

import argparse
import csv
import gc
import os
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "geometry.csv"

# ------------------------------------------------------------------------------ harness


@dataclass
class Timing:
    """Medians of repeated runs of one callable."""

    wall_s: float
    cpu_s: float
    repeats: int


@dataclass
class Row:
    """One line of the report: a measurement, optionally against a baseline."""

    section: str
    name: str
    wall_s: float
    cpu_s: float
    repeats: int
    baseline: str = ""
    baseline_wall_s: float = float("nan")
    baseline_cpu_s: float = float("nan")
    unit: str = ""
    value: float = float("nan")
    note: str = ""

    @property
    def speedup_wall(self) -> float:
        """Baseline wall time / this wall time (> 1: faster than the baseline)."""
        return self.baseline_wall_s / self.wall_s if self.wall_s > 0 else float("nan")

    @property
    def speedup_cpu(self) -> float:
        """Baseline CPU time / this CPU time."""
        return self.baseline_cpu_s / self.cpu_s if self.cpu_s > 0 else float("nan")


def measure(fn: Callable[[], object], repeats: int, warmup: int = 1) -> Timing:
    """Median wall and CPU seconds of ``fn()`` over ``repeats`` runs after ``warmup`` runs."""
    for _ in range(warmup):
        fn()
    walls, cpus = [], []
    for _ in range(repeats):
        gc.collect()
        c0, w0 = time.process_time(), time.perf_counter()
        fn()
        w1, c1 = time.perf_counter(), time.process_time()
        walls.append(w1 - w0)
        cpus.append(c1 - c0)
    return Timing(statistics.median(walls), statistics.median(cpus), repeats)


@dataclass
class Bench:
    """Collects rows; sections call :meth:`compare`, :meth:`measure` and :meth:`note`."""

    quick: bool
    data: Path
    rows: list[Row] = field(default_factory=list)

    def reps(self, full: int, quick: int = 1) -> int:
        """Number of repeats: ``full``, or ``quick`` with ``--quick``."""
        return quick if self.quick else full

    def measure(self, section: str, name: str, fn, repeats: int, **extra) -> Row:
        """Time ``fn`` alone (no baseline) and record it."""
        t = measure(fn, repeats)
        row = Row(section, name, t.wall_s, t.cpu_s, t.repeats, **extra)
        self.rows.append(row)
        return row

    def compare(
        self,
        section: str,
        name: str,
        fn,
        baseline_name: str,
        baseline,
        repeats: int,
        baseline_repeats: int | None = None,
        **extra,
    ) -> Row:
        """Time ``fn`` and ``baseline`` in the same run and record their ratio.

        ``baseline`` may be a callable or an already measured :class:`Timing` (reuse one
        baseline for several candidates).
        """
        t = measure(fn, repeats)
        if isinstance(baseline, Timing):
            b = baseline
        else:
            b = measure(baseline, baseline_repeats or repeats)
        row = Row(
            section,
            name,
            t.wall_s,
            t.cpu_s,
            t.repeats,
            baseline=baseline_name,
            baseline_wall_s=b.wall_s,
            baseline_cpu_s=b.cpu_s,
            **extra,
        )
        self.rows.append(row)
        return row

    def note(self, section: str, text: str) -> None:
        """A line without timing (e.g. a baseline that is not installed)."""
        self.rows.append(Row(section, "note", float("nan"), float("nan"), 0, note=text))

    def report(self, path: Path = RESULTS) -> None:
        """Print the table and write the CSV."""

        def fmt_s(x: float) -> str:
            if not np.isfinite(x):
                return ""
            if x >= 1:
                return f"{x:.2f} s"
            if x >= 1e-3:
                return f"{x * 1e3:.2f} ms"
            return f"{x * 1e6:.1f} us"

        def fmt_x(x: float) -> str:
            return f"{x:.1f}x" if np.isfinite(x) else ""

        head = ["section", "measurement", "wall", "cpu", "baseline", "b. wall", "b. cpu",
                "speedup wall", "speedup cpu", "value", "note"]
        lines = []
        for r in self.rows:
            value = f"{r.value:.3g} {r.unit}" if np.isfinite(r.value) else ""
            lines.append([r.section, r.name, fmt_s(r.wall_s), fmt_s(r.cpu_s), r.baseline,
                          fmt_s(r.baseline_wall_s), fmt_s(r.baseline_cpu_s),
                          fmt_x(r.speedup_wall), fmt_x(r.speedup_cpu), value, r.note])
        widths = [max(len(str(x)) for x in col) for col in zip(head, *lines)]
        for line in [head, ["-" * w for w in widths], *lines]:
            print("  ".join(str(x).ljust(w) for x, w in zip(line, widths)).rstrip())
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["section", "name", "wall_s", "cpu_s", "repeats", "baseline",
                        "baseline_wall_s", "baseline_cpu_s", "speedup_wall", "speedup_cpu",
                        "value", "unit", "note"])
            for r in self.rows:
                w.writerow([r.section, r.name, r.wall_s, r.cpu_s, r.repeats, r.baseline,
                            r.baseline_wall_s, r.baseline_cpu_s, r.speedup_wall, r.speedup_cpu,
                            r.value, r.unit, r.note])
        print(f"\nwrote {path.relative_to(REPO) if path.is_relative_to(REPO) else path}")


SECTIONS: dict[str, Callable[[Bench], None]] = {}


def section(name: str):
    """Register a benchmark section ``fn(bench)`` under ``name`` (run in definition order)."""

    def deco(fn: Callable[[Bench], None]) -> Callable[[Bench], None]:
        SECTIONS[name] = fn
        return fn

    return deco


def _mobility_objs(bench: Bench) -> list[list[Path]]:
    """OBJ paths of each partnet-mobility object (a subset of 12 objects with --quick)."""
    folders = sorted(p for p in (bench.data / "partnet-mobility").iterdir() if p.is_dir())
    if bench.quick:
        folders = folders[:: max(1, len(folders) // 12)][:12]
    return [sorted((f / "textured_objs").glob("*.obj")) for f in folders]


# ------------------------------------------------------------------------------ sections


@section("load")
def bench_load(bench: Bench) -> None:
    import trimesh

    from kinmo.geometry import load_obj, load_objs

    objects = _mobility_objs(bench)
    paths = [p for obj in objects for p in obj]
    what = f"{len(objects)} objects, {len(paths)} OBJ files"

    def with_trimesh():
        for p in paths:
            trimesh.load(p, force="mesh", process=False)

    base = measure(with_trimesh, bench.reps(1), warmup=0)
    bench.compare("load", f"load_objs, all at once ({what})", lambda: load_objs(paths),
                  "trimesh.load per file", base, bench.reps(5, 2))
    bench.compare("load", "load_objs per object (one call per object)",
                  lambda: [load_objs(obj) for obj in objects], "trimesh.load per file", base,
                  bench.reps(5, 2))
    bench.compare("load", "load_obj per file (sequential)",
                  lambda: [load_obj(p) for p in paths], "trimesh.load per file", base,
                  bench.reps(3, 1))


@section("sampling")
def bench_sampling(bench: Bench) -> None:
    import trimesh

    from kinmo.geometry import load_objs, sample_surface, sample_surface_groups

    paths = [p for obj in _mobility_objs(bench) for p in obj]
    meshes = load_objs(paths)
    # Parts with positive area (sampling a zero-area part is an error on both sides).
    areas = [0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                  axis=1).sum() if len(f) else 0.0 for v, f in meshes]
    meshes = [m for m, a in zip(meshes, areas) if a > 0]
    tms = [trimesh.Trimesh(v, f, process=False) for v, f in meshes]
    n, k = 1024, len(meshes)
    n_faces = np.array([len(f) for _, f in meshes])
    what = f"{k} parts, {n} points each, faces median {int(np.median(n_faces))}"

    def with_trimesh():
        for i, m in enumerate(tms):
            trimesh.sample.sample_surface(m, n, seed=i)

    base = measure(with_trimesh, bench.reps(3, 1))
    row = bench.compare("sampling", f"sample_surface per part ({what})",
                        lambda: [sample_surface(v, f, n, i) for i, (v, f) in enumerate(meshes)],
                        "trimesh.sample.sample_surface", base, bench.reps(5, 2))
    row.value, row.unit = row.wall_s / k * 1e6, "us/part (rust)"
    bench.rows.append(Row("sampling", "trimesh per part", base.wall_s / k, base.cpu_s / k,
                          base.repeats, value=base.wall_s / k * 1e6, unit="us/part (trimesh)"))
    groups = [[i] for i in range(k)]
    row = bench.compare("sampling", "sample_surface_groups, all parts in one call",
                        lambda: sample_surface_groups(meshes, groups, n, 0),
                        "trimesh.sample.sample_surface", base, bench.reps(5, 2))
    row.value, row.unit = row.wall_s / k * 1e6, "us/part (rust)"
    bench.note("sampling", "open3d: not installed (optional 'bench' extra), not measured")


@section("motion")
def bench_motion(bench: Bench) -> None:
    from kinmo.geometry import apply_motions, motion_transforms

    rng = np.random.default_rng(0)
    c, n = (64, 4096) if bench.quick else (256, 8192)
    points = rng.normal(size=(n, 3))
    o = rng.normal(size=(c, 3))
    d = rng.normal(size=(c, 3))
    a = rng.uniform(-np.pi, np.pi, c)
    t = rng.normal(size=c)
    out_bytes = c * n * 3 * 8

    def with_numpy():
        m = motion_transforms(o, d, a, t)
        return np.matmul(points, m[:, :3, :3].transpose(0, 2, 1)) + m[:, None, :3, 3]

    def with_einsum():
        m = motion_transforms(o, d, a, t)
        return np.einsum("cij,nj->cni", m[:, :3, :3], points) + m[:, None, :3, 3]

    base = measure(with_numpy, bench.reps(7, 3))
    what = f"C={c} candidates x N={n} points, {out_bytes / 2**20:.0f} MiB out"
    row = bench.compare("motion", f"apply_motions ({what})",
                        lambda: apply_motions(points, o, d, a, t),
                        "numpy matmul with motion_transforms", base, bench.reps(7, 3))
    row.value, row.unit = out_bytes / row.wall_s / 1e9, "GB/s written"
    bench.compare("motion", "apply_motions", lambda: apply_motions(points, o, d, a, t),
                  "numpy einsum with motion_transforms", with_einsum, bench.reps(7, 3))
    # Memory-copy bandwidth: a numpy copy of a large array (fresh output, like both above).
    big = rng.normal(size=max(out_bytes, 256 * 2**20) // 8)
    cp = measure(lambda: big.copy(), bench.reps(7, 3))
    copy_bw = big.nbytes / cp.wall_s
    bench.rows.append(Row("motion", f"numpy copy of {big.nbytes / 2**20:.0f} MiB", cp.wall_s,
                          cp.cpu_s, cp.repeats, value=copy_bw / 1e9, unit="GB/s written"))
    frac = out_bytes / row.wall_s / copy_bw
    bench.rows.append(Row("motion", "apply_motions write bandwidth / copy bandwidth",
                          float("nan"), float("nan"), 0, value=frac, unit="of memcpy",
                          note="target >= 0.5"))
    bench.compare("motion", f"motion_transforms (C={c})",
                  lambda: motion_transforms(o, d, a, t), "scipy Rotation.from_rotvec",
                  lambda: _scipy_transforms(o, d, a, t), bench.reps(7, 3))


def _scipy_transforms(o, d, a, t):
    from scipy.spatial.transform import Rotation

    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    r = Rotation.from_rotvec(u * a[:, None]).as_matrix()
    m = np.tile(np.eye(4), (len(o), 1, 1))
    m[:, :3, :3] = r
    m[:, :3, 3] = o - np.einsum("cij,cj->ci", r, o) + t[:, None] * u
    return m


# ------------------------------------------------------------------------------ contact


def _leaf_meshes(folder: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """One mesh per leaf of ``result.json`` (the leaf's OBJ files merged), in pre-order."""
    import json

    from kinmo.geometry import load_objs

    leaves: list[list[str]] = []

    def walk(node: dict) -> None:
        if node.get("children"):
            for c in node["children"]:
                walk(c)
        elif node.get("objs"):
            leaves.append(node["objs"])

    for root in json.loads((folder / "result.json").read_text()):
        walk(root)
    names = sorted({n for objs in leaves for n in objs})
    loaded = dict(zip(names, load_objs([folder / "textured_objs" / f"{n}.obj" for n in names])))
    meshes = []
    for objs in leaves:
        parts = [loaded[n] for n in objs]
        offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
        meshes.append((np.concatenate([v for v, _ in parts]),
                       np.concatenate([f + o for (_, f), o in zip(parts, offsets)])))
    return meshes


def _fcl_all_pairs(meshes, prefilter_tol: float | None = None) -> dict[tuple[int, int], float]:
    """FCL: build one OBBRSS ``BVHModel`` per mesh, then ``fcl.distance`` of every pair.

    With ``prefilter_tol``, pairs whose vertex AABBs are farther apart are skipped (a
    numpy broad phase, the fairest FCL pipeline for a tolerance query).
    """
    import fcl

    objs = []
    for v, f in meshes:
        m = fcl.BVHModel()
        m.beginModel(len(v), len(f))
        m.addSubModel(v, f.astype(np.int32))
        m.endModel()
        objs.append(fcl.CollisionObject(m, fcl.Transform()))
    n = len(objs)
    if prefilter_tol is None:
        cand = [(i, j) for i in range(n) for j in range(i + 1, n)]
    else:
        lo = np.array([v.min(0) for v, _ in meshes])
        hi = np.array([v.max(0) for v, _ in meshes])
        cand = []
        for i in range(n):
            gap = np.maximum(0.0, np.maximum(lo[i + 1:] - hi[i], lo[i] - hi[i + 1:]))
            cand += [(i, int(j)) for j in np.flatnonzero(np.linalg.norm(gap, axis=1)
                                                         <= prefilter_tol) + i + 1]
    req = fcl.DistanceRequest()
    return {(i, j): max(fcl.distance(objs[i], objs[j], req, fcl.DistanceResult()), 0.0)
            for i, j in cand}


def _sampled_pairs(tms, tol: float, n: int) -> set[tuple[int, int]]:
    """Pairs of meshes with sampled surface points within ``tol`` (trimesh + scipy).

    ``n`` points per mesh (``trimesh.sample.sample_surface``), one ``cKDTree`` per mesh, and
    for every pair whose point AABBs are within ``tol``, a nearest-neighbour query bounded by
    ``tol``. Same pairs as ``cKDTree.query_pairs(tol)`` over all points, without enumerating
    the (many) close pairs inside each mesh.
    """
    import trimesh
    from scipy.spatial import cKDTree

    pts = [trimesh.sample.sample_surface(m, n, seed=k)[0] for k, m in enumerate(tms)]
    trees = [cKDTree(p) for p in pts]
    lo = np.array([p.min(0) for p in pts])
    hi = np.array([p.max(0) for p in pts])
    out = set()
    for i in range(len(pts)):
        gap = np.maximum(0.0, np.maximum(lo[i + 1:] - hi[i], lo[i] - hi[i + 1:]))
        for j in np.flatnonzero(np.linalg.norm(gap, axis=1) <= tol) + i + 1:
            d, _ = trees[j].query(pts[i], distance_upper_bound=tol)
            if np.any(d <= tol):
                out.add((i, int(j)))
    return out


@section("contact")
def bench_contact(bench: Bench) -> None:
    """Contact adjacency of the leaves of every PartNet-Mobility object.

    Tolerance ``0.01 × diagonal`` (kinmo's default relative tolerance). Baselines: FCL
    (OBBRSS BVH build + ``fcl.distance`` of all pairs, the exact reference), FCL with a numpy
    AABB prefilter, and the sampled approach (trimesh ``sample_surface``, 2048 points per
    leaf, scipy ``cKDTree`` queries within the tolerance), whose missed pairs are counted.
    """
    import trimesh

    from kinmo.geometry import contact_pairs

    folders = sorted(p for p in (bench.data / "partnet-mobility").iterdir() if p.is_dir())
    if bench.quick:
        folders = folders[:: max(1, len(folders) // 12)][:12]
    n_samples = 2048
    rows = []  # per object: timings and pair sets
    for folder in folders:
        meshes = _leaf_meshes(folder)
        if len(meshes) < 2:
            continue
        allv = np.concatenate([v for v, _ in meshes])
        diag = float(np.linalg.norm(allv.max(0) - allv.min(0)))
        tol = 0.01 * diag
        tms = [trimesh.Trimesh(v, f, process=False) for v, f in meshes]
        reps = bench.reps(5, 2)
        got = contact_pairs(meshes, tol)
        k = measure(lambda: contact_pairs(meshes, tol), reps)
        k_cap = measure(lambda: contact_pairs(meshes, 0.1 * diag), reps)
        fcl_d = _fcl_all_pairs(meshes)
        f_all = measure(lambda: _fcl_all_pairs(meshes), bench.reps(3, 1), warmup=0)
        f_pre = measure(lambda: _fcl_all_pairs(meshes, tol), bench.reps(3, 1), warmup=0)
        s = measure(lambda: _sampled_pairs(tms, tol, n_samples), bench.reps(3, 1), warmup=0)
        exact = {(int(i), int(j)) for i, j in got[0]}
        ref = {p for p, d in fcl_d.items() if d <= tol}
        mismatch = {p for p in exact ^ ref if abs(fcl_d[p] - tol) > 1e-6 * diag}
        sampled = _sampled_pairs(tms, tol, n_samples)
        rows.append(dict(id=folder.name, n=len(meshes), faces=sum(len(f) for _, f in meshes),
                         k=k, k_cap=k_cap, f_all=f_all, f_pre=f_pre, s=s, exact=len(exact),
                         mismatch=len(mismatch), missed=len(exact - sampled),
                         extra=len(sampled - exact)))
    if not rows:
        bench.note("contact", "no object with two leaves")
        return
    what = (f"{len(rows)} objects, leaves median {int(np.median([r['n'] for r in rows]))} "
            f"max {max(r['n'] for r in rows)}, tol 0.01 diag")

    def total(key: str, attr: str) -> float:
        return float(sum(getattr(r[key], attr) for r in rows))

    def add(name: str, key: str, base_key: str, base_name: str) -> None:
        row = Row("contact", name, total(key, "wall_s"), total(key, "cpu_s"), rows[0][key].repeats,
                  baseline=base_name, baseline_wall_s=total(base_key, "wall_s"),
                  baseline_cpu_s=total(base_key, "cpu_s"))
        ratios = [r[base_key].wall_s / r[key].wall_s for r in rows]
        row.value, row.unit = float(np.median(ratios)), "x median per-object wall ratio"
        row.note = f"min per-object ratio {min(ratios):.1f}x"
        bench.rows.append(row)

    add(f"contact_pairs, sum over objects ({what})", "k", "f_all", "FCL build + all-pairs distance")
    add("contact_pairs", "k", "f_pre", "FCL build + AABB-prefiltered distance")
    add("contact_pairs", "k", "s", f"sampled: trimesh {n_samples} pts/leaf + cKDTree")
    add("contact_pairs, tol 0.1 diag (graph distance cap)", "k_cap", "f_all",
        "FCL build + all-pairs distance")
    n_exact = sum(r["exact"] for r in rows)
    bench.rows.append(Row(
        "contact", "pairs differing from FCL (beyond 1e-6 diag of the boundary)", float("nan"),
        float("nan"), 0, value=sum(r["mismatch"] for r in rows), unit=f"of {n_exact} pairs"))
    missed = [r for r in rows if r["missed"]]
    bench.rows.append(Row(
        "contact", f"pairs missed by the sampled approach ({n_samples} pts/leaf)", float("nan"),
        float("nan"), 0, value=sum(r["missed"] for r in rows), unit=f"of {n_exact} pairs",
        note=f"{len(missed)} of {len(rows)} objects affected; "
             f"{sum(r['extra'] for r in rows)} extra pairs"))
    per_obj = [r["k"].wall_s * 1e3 for r in rows]
    bench.rows.append(Row("contact", "contact_pairs per object", float(np.median(per_obj)) / 1e3,
                          float(np.median([r["k"].cpu_s for r in rows])), rows[0]["k"].repeats,
                          value=max(per_obj), unit="ms max per object"))


@section("interaction")
def bench_interaction(bench: Bench) -> None:
    """Interaction region of two touching clouds vs scipy (two cKDTrees, nearest distance)."""
    from scipy.spatial import cKDTree

    from kinmo.geometry import interaction_region

    rng = np.random.default_rng(0)
    n = 20000 if bench.quick else 100000
    a = rng.uniform(0, 1, (n, 3))
    b = rng.uniform(0, 1, (n, 3)) + [0.95, 0, 0]
    r = 0.02

    def with_scipy():
        ma = cKDTree(b).query(a, distance_upper_bound=r)[0] <= r
        mb = cKDTree(a).query(b, distance_upper_bound=r)[0] <= r
        return np.concatenate([a[ma], b[mb]]).mean(0)

    bench.compare("interaction", f"interaction_region ({n} + {n} points, radius {r})",
                  lambda: interaction_region(a, b, r), "scipy cKDTree x2 + query", with_scipy,
                  bench.reps(7, 3))


# ------------------------------------------------------------------------------ obb


def _obb_axes_trimesh(to_origin: np.ndarray) -> np.ndarray:
    """Rows of the box axes of ``trimesh.bounds.oriented_bounds`` (its rotation's rows)."""
    return np.asarray(to_origin)[:3, :3]


@section("obb")
def bench_obb(bench: Bench) -> None:
    """Per-part OBB fitting on every leaf part (OBJ) of ``partnet-mobility/``.

    Times one :func:`~kinmo.geometry.fit_obb` call and one ``trimesh.bounds.oriented_bounds``
    call per part (both on the part's vertices), reports the median per-part times and their
    ratio, :func:`~kinmo.geometry.fit_obb_batch` on all parts at once, and the tightness
    against trimesh: volume ratio per part (in-plane area for *flat* parts, whose box is
    thinner than 1e-4 of its longest side: their thickness is coordinate rounding noise),
    the fractions tighter by > 0.1% / equal within 0.1% / looser by > 0.1%, the largest
    ratio, and how many boxes have an axis exactly along +y (up).
    """
    import trimesh

    from kinmo.geometry import fit_obb, fit_obb_batch, load_objs

    paths = [p for obj in _mobility_objs(bench) for p in obj]
    parts = [v for v, _ in load_objs(paths) if len(v)]
    k = len(parts)
    n_verts = np.array([len(v) for v in parts])
    what = f"{k} parts, vertices median {int(np.median(n_verts))}, max {n_verts.max()}"
    ours_t, theirs_t, ratios, up_ours, up_theirs, flat, tm_failed = [], [], [], 0, 0, 0, 0
    for v in parts:
        fit_obb(v)  # warm caches; the timed call below is the second one
        t0 = time.perf_counter()
        b = fit_obb(v)
        t1 = time.perf_counter()
        try:
            to_origin, ext = trimesh.bounds.oriented_bounds(v)
        except Exception:  # trimesh fails on some degenerate parts; kinmo does not
            tm_failed += 1
            continue
        t2 = time.perf_counter()
        ours_t.append(t1 - t0)
        theirs_t.append(t2 - t1)
        ext = np.sort(ext)[::-1]
        h = b.half_extents
        if h[2] < 1e-4 * h[0]:
            flat += 1
            ours, theirs = 4 * h[0] * h[1], ext[0] * ext[1]
        else:
            ours, theirs = b.volume, float(np.prod(ext))
        ratios.append(ours / theirs if theirs > 0 else (1.0 if ours == 0 else np.inf))
        up_ours += bool(np.abs(b.axes[:, 1]).max() >= 1 - 1e-12)
        up_theirs += bool(np.abs(_obb_axes_trimesh(to_origin)[:, 1]).max() >= 1 - 1e-12)
    med, med_tm = statistics.median(ours_t), statistics.median(theirs_t)
    bench.rows.append(Row("obb", f"fit_obb per part, median ({what})", med, float("nan"), 1,
                          baseline="trimesh.bounds.oriented_bounds per part, median",
                          baseline_wall_s=med_tm, value=med_tm / med, unit="x faster (median)",
                          note="target >= 10x"))
    bench.rows.append(Row("obb", "fit_obb all parts, sequential sum", sum(ours_t), float("nan"),
                          1, baseline="trimesh, sequential sum", baseline_wall_s=sum(theirs_t)))
    base = Timing(sum(theirs_t), float("nan"), 1)
    bench.compare("obb", "fit_obb_batch, all parts in one call", lambda: fit_obb_batch(parts),
                  "trimesh, sequential sum", base, bench.reps(3, 1))
    r = np.array(ratios)
    for name, frac in [("tighter than trimesh by > 0.1%", np.mean(r < 0.999)),
                       ("equal to trimesh within 0.1%", np.mean((r >= 0.999) & (r <= 1.001))),
                       ("looser than trimesh by > 0.1% (<= 1%: up/symmetry choice)",
                        np.mean(r > 1.001))]:
        bench.rows.append(Row("obb", name, float("nan"), float("nan"), 0, value=frac,
                              unit="of parts"))
    bench.rows.append(Row("obb", "max volume ratio kinmo / trimesh", float("nan"), float("nan"),
                          0, value=float(r.max()), unit="", note="required <= 1.01"))
    bench.rows.append(Row("obb", "min volume ratio kinmo / trimesh", float("nan"), float("nan"),
                          0, value=float(r.min()), unit=""))
    if tm_failed:
        bench.note("obb", f"trimesh raised on {tm_failed} part(s) (left out of the comparison)")
    k = len(ratios)
    bench.rows.append(Row("obb", f"flat parts (area compared), of {k}", float("nan"),
                          float("nan"), 0, value=flat, unit="parts"))
    bench.rows.append(Row("obb", "boxes with an axis exactly along +y: kinmo", float("nan"),
                          float("nan"), 0, value=up_ours / k, unit="of parts",
                          note=f"trimesh: {up_theirs / k:.3f}"))


# ------------------------------------------------------------------------------ before/after


def _load_core(path: Path):
    """Import a ``_core`` extension module from ``path`` (e.g. a copy of an older build)."""
    import importlib.machinery
    import importlib.util

    loader = importlib.machinery.ExtensionFileLoader("_core", str(path))
    spec = importlib.util.spec_from_file_location("_core", path, loader=loader)
    mod = importlib.util.module_from_spec(spec)
    loader.exec_module(mod)
    return mod


OLD_CORE: Path | None = None  # set by --old-core


@section("before-after")
def bench_before_after(bench: Bench) -> None:
    """Today's ``kinmo._core`` against an older build (``--old-core PATH``) in one run.

    Written for issue 13 (the core moved onto parry3d-f64, kiddo and rand_xoshiro): the
    same inputs through both modules, the median per-object/per-call ratio, and checks that
    the outputs agree (contact pairs and distances, sampled points bit for bit, OBB volumes).
    Contact adjacency is also compared with FCL (build + all-pairs distance), which it must
    beat by at least 10x. Skipped (a note) without ``--old-core``.
    """
    from kinmo import _core as new

    if OLD_CORE is None:
        bench.note("before-after", "no --old-core given")
        return
    old = _load_core(OLD_CORE)
    sec = "before-after"
    # Contact adjacency on every object's leaves.
    folders = sorted(p for p in (bench.data / "partnet-mobility").iterdir() if p.is_dir())
    if bench.quick:
        folders = folders[:: max(1, len(folders) // 12)][:12]
    per, differ, n_pairs = [], 0, 0
    for folder in folders:
        meshes = _leaf_meshes(folder)
        if len(meshes) < 2:
            continue
        allv = np.concatenate([v for v, _ in meshes])
        tol = 0.01 * float(np.linalg.norm(allv.max(0) - allv.min(0)))
        a, b = new.contact_pairs(meshes, tol), old.contact_pairs(meshes, tol)
        n_pairs += len(a[0])
        if a[0].tolist() != b[0].tolist() or not np.allclose(a[1], b[1], rtol=0, atol=1e-9 * tol):
            differ += 1
        reps = bench.reps(5, 2)
        per.append((measure(lambda: new.contact_pairs(meshes, tol), reps),
                    measure(lambda: old.contact_pairs(meshes, tol), reps),
                    measure(lambda: _fcl_all_pairs(meshes), bench.reps(3, 1), warmup=0)))
    for k, base in [(1, "old kinmo._core (own BVH + sweep-and-prune)"),
                    (2, "FCL build + all-pairs distance")]:
        ratios = [p[k].wall_s / p[0].wall_s for p in per]
        cpu = [p[k].cpu_s / p[0].cpu_s for p in per]
        bench.rows.append(Row(
            sec, f"contact_pairs, sum over {len(per)} objects", sum(p[0].wall_s for p in per),
            sum(p[0].cpu_s for p in per), per[0][0].repeats, baseline=base,
            baseline_wall_s=sum(p[k].wall_s for p in per),
            baseline_cpu_s=sum(p[k].cpu_s for p in per), value=float(np.median(ratios)),
            unit="x median per-object wall ratio (baseline / new)",
            note=f"min per-object {min(ratios):.2f}x; cpu: median {np.median(cpu):.2f}x, "
                 f"min {min(cpu):.2f}x"))
    bench.rows.append(Row(sec, "objects whose contact pairs differ new vs old", float("nan"),
                          float("nan"), 0, value=differ,
                          unit=f"of {len(per)} objects ({n_pairs} pairs, atol 1e-9 tol)"))
    # OBB per part (hull + kiddo symmetry tree).
    paths = [p for obj in _mobility_objs(bench) for p in obj]
    parts = [v for v, _ in new.load_objs([str(p) for p in paths]) if len(v)]
    vol = lambda r: 8 * float(np.prod(r[2]))  # noqa: E731
    worse = sum(vol(new.fit_obb(v)) > vol(old.fit_obb(v)) * (1 + 1e-9) for v in parts)
    bench.compare(sec, f"fit_obb_batch, {len(parts)} parts", lambda: new.fit_obb_batch(parts),
                  "old kinmo._core", lambda: old.fit_obb_batch(parts), bench.reps(3, 1))
    bench.rows.append(Row(sec, "parts whose OBB volume grew new vs old", float("nan"),
                          float("nan"), 0, value=worse, unit=f"of {len(parts)} parts"))
    rng = np.random.default_rng(0)
    sphere = rng.normal(size=(20000, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    bench.rows.append(_compare_once(sec, "fit_obb, 20 000 points on a sphere (all on the hull)",
                                    lambda: new.fit_obb(sphere), lambda: old.fit_obb(sphere)))
    # Interaction region (kiddo k-d trees).
    n = 20000 if bench.quick else 100000
    a = rng.uniform(0, 1, (n, 3))
    b = rng.uniform(0, 1, (n, 3)) + [0.95, 0, 0]
    same = all(np.array_equal(x, y) for x, y in zip(new.interaction_region(a, b, 0.02)[:3],
                                                     old.interaction_region(a, b, 0.02)[:3]))
    bench.compare(sec, f"interaction_region ({n} + {n} points, radius 0.02)",
                  lambda: new.interaction_region(a, b, 0.02), "old kinmo._core",
                  lambda: old.interaction_region(a, b, 0.02), bench.reps(7, 3),
                  note=f"identical output: {same}")
    # Sampling (rand_xoshiro): bit-identical and as fast.
    meshes = _leaf_meshes(folders[0])
    groups = [[i] for i in range(len(meshes))]
    same = np.array_equal(new.sample_surface_groups(meshes, groups, 4096, 7),
                          old.sample_surface_groups(meshes, groups, 4096, 7))
    bench.compare(sec, f"sample_surface_groups ({len(groups)} groups x 4096 points)",
                  lambda: new.sample_surface_groups(meshes, groups, 4096, 7), "old kinmo._core",
                  lambda: old.sample_surface_groups(meshes, groups, 4096, 7), bench.reps(7, 3),
                  note=f"bit-identical output: {same}")


def _compare_once(sec: str, name: str, fn, base) -> Row:
    """One timed call of each (for slow baselines), as a row."""
    t = measure(fn, 1, warmup=0)
    b = measure(base, 1, warmup=0)
    return Row(sec, name, t.wall_s, t.cpu_s, 1, baseline="old kinmo._core",
               baseline_wall_s=b.wall_s, baseline_cpu_s=b.cpu_s)


# ------------------------------------------------------------------------------ main


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="subsets and fewer repeats")
    ap.add_argument("--only", default="", help="comma-separated sections: " + ", ".join(SECTIONS))
    ap.add_argument("--data", type=Path,
                    default=Path(os.environ.get("KINMO_DATA", REPO.parent / "shared" / "data")))
    ap.add_argument("--csv", type=Path, default=RESULTS)
    ap.add_argument("--old-core", type=Path, default=None,
                    help="an older _core*.so for the before-after section")
    args = ap.parse_args(argv)
    global OLD_CORE
    OLD_CORE = args.old_core
    names = [s for s in args.only.split(",") if s] or list(SECTIONS)
    unknown = [s for s in names if s not in SECTIONS]
    if unknown:
        ap.error(f"unknown section(s) {unknown}; known: {list(SECTIONS)}")
    bench = Bench(quick=args.quick, data=args.data)
    rayon = os.environ.get("RAYON_NUM_THREADS", "")
    print(f"threads: {os.cpu_count()} cpus, RAYON_NUM_THREADS={rayon}", file=sys.stderr)
    print("note: parallel code shows cpu > wall only when a second core is free; on a "
          "loaded shared machine compare the cpu columns", file=sys.stderr)
    for s in names:
        print(f"[{s}] ...", file=sys.stderr, flush=True)
        SECTIONS[s](bench)
    bench.report(args.csv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
