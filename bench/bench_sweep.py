"""Benchmark of the swept-collision test (:func:`kinmo.geometry.sweep_collisions`, Rust on
parry) against the same test done with trimesh ray casts, in the same run.

Workload, as refinement makes it: for every moving link (hinge or slider) of a few real
PartNet-Mobility objects, 512 surface points of the moving part (its rigid group), the
obstacle = every other rigid group concatenated, and the candidate motions of the moving
part's OBB: for each of its 3 axes the 4 parallel OBB edges and the centre line as revolute
axes (pi/2) and the axis as a prismatic direction (the box's extent along it): 18 candidates
x 2 signs x 16 steps x 512 points per link, in one call.

Baseline: the identical rule (module docstring of :mod:`kinmo.geometry.sweep`: chords of
each step, first counted crossing, contact at rest within ``skin``: first-step crossings
closer than ``skin``, triangles touched at rest and the rest tangent slab do not count),
vectorised with numpy over all rays of a link and cast with trimesh's
``intersects_location(multiple_hits=True)``: Embree (``embreex``, single precision, trimesh's
fast path) for every link, and trimesh's pure-numpy ``ray_triangle`` (rtree) on the first
link only (it is ~100x slower). Rest contacts come from ``trimesh.proximity.closest_point``.
Timings are medians of repeats (wall and CPU of the process), reported as ratios; agreement
of the outputs is the share of candidate-signs whose ``free_fraction`` and
``colliding_fraction`` differ by at most 0.02, and the largest difference.

Needs ``rtree`` (trimesh's ``ray_triangle`` and ``proximity``) and ``embreex`` (Embree),
which the test environment does not install: they are in the ``bench`` extra of
``pyproject.toml`` (``pip install rtree embreex``).

Usage::

    RAYON_NUM_THREADS=1 python bench/bench_sweep.py [--quick] [--shapes 45001,12252,...]

Also :func:`kinmo.geometry.line_mesh_distance` (exact, by projecting the mesh along each
line; Rust, rayon over lines) on the same candidate lines and obstacle against the same
projection vectorised in numpy (``numpy_line_mesh_distance``), with the largest difference.

Prints a table and writes ``bench/results/sweep.csv``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))

from bench_geometry import Bench  # noqa: E402

RESULTS = REPO / "bench" / "results" / "sweep.csv"
SHAPES = ["45001", "12252", "10905", "45463", "11709", "26657", "12553"]
N_POINTS, N_STEPS = 512, 16


def _rigid_group_mesh(shape, link_ids):
    from kinmo.geometry import load_objs

    names = sorted(
        {n for lk in shape.links if lk.id in link_ids for p in lk.parts
         for n in shape.hierarchy.mesh_names(p)}
    )
    meshes = load_objs([str(shape.mesh_dir / f"{n}.obj") for n in names])
    offsets = np.cumsum([0] + [len(m[0]) for m in meshes[:-1]])
    return (np.concatenate([m[0] for m in meshes]),
            np.concatenate([m[1] + o for m, o in zip(meshes, offsets)]))


def workloads(data: Path, shape_ids: list[str]):
    """Yield ``(name, points, vertices, faces, origins, directions, kinds, ranges)``."""
    from kinmo.data.labels import rigid_groups
    from kinmo.data.readers import read_shape
    from kinmo.geometry import fit_obb, sample_surface

    for sid in shape_ids:
        shape = read_shape(data / "partnet-mobility" / sid)
        groups = rigid_groups(shape.links)
        done = set()
        for lk in shape.links:
            if not lk.joint.is_moving or groups[lk.id] in done:
                continue
            done.add(groups[lk.id])
            moving = {x.id for x in shape.links if groups[x.id] == groups[lk.id]}
            rest = {x.id for x in shape.links} - moving
            if not rest:
                continue
            mv, mf = _rigid_group_mesh(shape, moving)
            ov, of = _rigid_group_mesh(shape, rest)
            pts, _ = sample_surface(mv, mf, N_POINTS, seed=0)
            center, axes, half = fit_obb(pts)
            origins, dirs, kinds, ranges = [], [], [], []
            for i in range(3):
                j, k = (i + 1) % 3, (i + 2) % 3
                for sj, sk in ((1, 1), (1, -1), (-1, 1), (-1, -1), (0, 0)):
                    origins.append(center + sj * half[j] * axes[j] + sk * half[k] * axes[k])
                    dirs.append(axes[i]), kinds.append(0), ranges.append(np.pi / 2)
                origins.append(center), dirs.append(axes[i]), kinds.append(1)
                ranges.append(2 * half[i])
            yield (f"{sid}/{lk.id} {shape.category} F={len(of)}", pts, ov, of,
                   np.array(origins), np.array(dirs), np.array(kinds), np.array(ranges))


def _rodrigues(u, angle):
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def trimesh_sweep(points, mesh, intersector, origins, dirs, kinds, ranges, skin,
                  n_steps=N_STEPS, hit_tolerance=0.02):
    """The swept test of :func:`kinmo.geometry.sweep_collisions` with trimesh ray casts."""
    import trimesh

    p = len(points)
    closest, dist, tri = trimesh.proximity.closest_point(mesh, points)
    contact = dist <= skin
    normals = mesh.face_normals[tri]
    bad = np.linalg.norm(normals, axis=1) < 0.5
    off = points - closest
    offn = np.linalg.norm(off, axis=1, keepdims=True)
    normals[bad] = np.where(offn[bad] > 1e-12, off[bad] / np.maximum(offn[bad], 1e-300), 0)
    free = np.ones((len(origins), 2))
    coll = np.zeros((len(origins), 2))
    # All segments of all candidate-signs of the call in one ray batch.
    seg_a, seg_b, seg_meta = [], [], []
    for c in range(len(origins)):
        u = dirs[c] / np.linalg.norm(dirs[c])
        for s, sign in enumerate((1.0, -1.0)):
            if kinds[c] == 1:
                pos = np.stack([points, points + sign * ranges[c] * u])
                steps = 1
            else:
                rot = _rodrigues(u, sign * ranges[c] / n_steps)
                pos = [points]
                for _ in range(n_steps):
                    pos.append((pos[-1] - origins[c]) @ rot.T + origins[c])
                pos = np.stack(pos)
                steps = n_steps
            seg_a.append(pos[:-1].reshape(-1, 3))
            seg_b.append(pos[1:].reshape(-1, 3))
            seg_meta.append((c, s, steps))
    a, b = np.concatenate(seg_a), np.concatenate(seg_b)
    v = b - a
    length = np.linalg.norm(v, axis=1)
    ok = length > 0
    d = np.where(ok[:, None], v / np.maximum(length, 1e-300)[:, None], [1.0, 0, 0])
    # Per ray: its point, its step; contact points start their first step `skin` later.
    point_of, step_of = [], []
    for _c, _s, steps in seg_meta:
        point_of.append(np.tile(np.arange(p), steps))
        step_of.append(np.repeat(np.arange(steps), p))
    point_of, step_of = np.concatenate(point_of), np.concatenate(step_of)
    t0 = np.where((step_of == 0) & contact[point_of], skin, 0.0)
    live = ok & (t0 < length)
    idx = np.flatnonzero(live)
    loc, ray, hit_tri = intersector.intersects_location(
        a[idx] + d[idx] * t0[idx, None], d[idx], multiple_hits=True
    )
    ray = idx[ray]
    t = np.einsum("ij,ij->i", loc - a[ray], d[ray])
    keep = (t >= t0[ray] - 1e-12) & (t <= length[ray])
    loc, ray, hit_tri, t = loc[keep], ray[keep], hit_tri[keep], t[keep]
    pt = point_of[ray]
    cont = contact[pt]
    if cont.any():
        cl = trimesh.triangles.closest_point(mesh.triangles[hit_tri[cont]], points[pt[cont]])
        touched = np.linalg.norm(cl - points[pt[cont]], axis=1) <= skin
        rel = loc[cont] - closest[pt[cont]]
        nrm = normals[pt[cont]]
        has_n = np.linalg.norm(nrm, axis=1) > 0.5
        slab = np.where(has_n, np.abs(np.einsum("ij,ij->i", rel, nrm)) <= skin,
                        np.linalg.norm(rel, axis=1) <= skin)
        exempt = np.zeros(len(t), bool)
        exempt[np.flatnonzero(cont)] = touched | slab
        ray, t = ray[~exempt], t[~exempt]
    first_t = np.full(len(a), np.inf)
    np.minimum.at(first_t, ray, t)
    start = 0
    m = int(np.floor(hit_tolerance * p)) + 1
    for c, s, steps in seg_meta:
        ft = first_t[start:start + steps * p].reshape(steps, p)
        ln = length[start:start + steps * p].reshape(steps, p)
        start += steps * p
        u_hit = np.full(p, np.inf)
        for k in range(steps - 1, -1, -1):  # earliest step wins
            h = np.isfinite(ft[k])
            u_hit[h] = (k + ft[k, h] / ln[k, h]) / steps
        hits = np.sort(u_hit[np.isfinite(u_hit)])
        coll[c, s] = len(hits) / p
        if len(hits) >= m:
            free[c, s] = min(max(hits[m - 1], 0.0), 1.0)
    return free, coll


def numpy_line_mesh_distance(origins, dirs, vertices, faces):
    """Baseline of :func:`kinmo.geometry.line_mesh_distance`, vectorised numpy: project the
    mesh along each line onto the orthogonal plane, then the 2D distance from the line's trace
    to every projected triangle (0 inside), the minimum over triangles."""
    out = np.empty(len(origins))
    for c, (o, u) in enumerate(zip(origins, dirs)):
        u = u / np.linalg.norm(u)
        a = np.eye(3)[np.argmin(np.abs(u))]
        e1 = np.cross(u, a)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        p = (vertices - o) @ np.stack([e1, e2], 1)  # (V, 2)
        t = p[faces]  # (F, 3, 2)
        a_, b_, c_ = t[:, 0], t[:, 1], t[:, 2]

        def cross(x, y):
            return x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0]

        s0, s1, s2 = cross(a_, b_), cross(b_, c_), cross(c_, a_)
        inside = ((s0 >= 0) & (s1 >= 0) & (s2 >= 0)) | ((s0 <= 0) & (s1 <= 0) & (s2 <= 0))
        inside &= (s0 + s1 + s2) != 0

        def seg(x, y):
            dd = y - x
            l2 = (dd ** 2).sum(1)
            tt = np.clip(-(x * dd).sum(1) / np.where(l2 > 0, l2, 1.0), 0.0, 1.0)
            q = x + tt[:, None] * dd
            return (q ** 2).sum(1)

        d2 = np.minimum(np.minimum(seg(a_, b_), seg(b_, c_)), seg(c_, a_))
        out[c] = 0.0 if inside.any() else float(np.sqrt(d2.min()))
    return out


def _agreement(a, b):
    (fa, ca), (fb, cb) = a, b
    df, dc = np.abs(fa - fb), np.abs(ca - cb)
    return float(np.mean((df <= 0.02) & (dc <= 0.02))), float(max(df.max(), dc.max()))


def run(bench: Bench, shape_ids: list[str]) -> None:
    import trimesh

    from kinmo.geometry import sweep_collisions
    from kinmo.geometry.sweep import default_skin

    try:
        import rtree  # noqa: F401  (trimesh's ray_triangle and proximity need it)
    except ImportError:
        raise SystemExit("bench_sweep: needs rtree (and embreex): pip install rtree embreex")

    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector as Embree
    except ImportError:  # pragma: no cover - embreex missing
        Embree = None
        bench.note("sweep", "embreex not installed: Embree baseline skipped")
    from trimesh.ray.ray_triangle import RayMeshIntersector as Triangle

    agree_all, shapes_s = [], []
    for i, (name, pts, ov, of, o, d, k, r) in enumerate(workloads(bench.data, shape_ids)):
        skin = default_skin(pts, ov)
        mesh = trimesh.Trimesh(ov, of, process=False)

        def rust(pts=pts, ov=ov, of=of, o=o, d=d, k=k, r=r, skin=skin):
            return sweep_collisions(pts, ov, of, o, d, k, r, skin=skin)

        got = rust()
        reps = bench.reps(7, 2)
        from kinmo.geometry import line_mesh_distance

        lines = np.ascontiguousarray(o), np.ascontiguousarray(d)
        lm = line_mesh_distance(*lines, ov, of)
        lm_ref = numpy_line_mesh_distance(*lines, ov, of)
        row = bench.compare(
            "line_mesh_distance", f"{name}: {len(o)} lines x {len(of)} faces",
            lambda: line_mesh_distance(*lines, ov, of), "numpy, same projection",
            lambda: numpy_line_mesh_distance(*lines, ov, of), reps,
            baseline_repeats=bench.reps(3, 1), unit="max |diff|",
            value=float(np.abs(lm - lm_ref).max()),
        )
        if Embree is not None:
            emb = Embree(mesh)
            ref = trimesh_sweep(pts, mesh, emb, o, d, k, r, skin)
            share, worst = _agreement(got, ref)
            agree_all.append(share)
            row = bench.compare(
                "sweep", f"{name}: {len(o)} cand x 2 x {N_STEPS} x {N_POINTS}", rust,
                "trimesh+embree", lambda: trimesh_sweep(pts, mesh, emb, o, d, k, r, skin),
                reps, baseline_repeats=bench.reps(3, 1),
                unit="agree share", value=share,
            )
            row.note = f"max |diff| {worst:.3f}"
            shapes_s.append(row.wall_s)
        if i == 0:
            tri = Triangle(mesh)
            sub = slice(0, 6 if not bench.quick else 2)
            ref = trimesh_sweep(pts, mesh, tri, o[sub], d[sub], k[sub], r[sub], skin)
            share, worst = _agreement(
                sweep_collisions(pts, ov, of, o[sub], d[sub], k[sub], r[sub], skin=skin), ref
            )
            row = bench.compare(
                "sweep", f"{name}: {len(o[sub])} cand (ray_triangle subset)",
                lambda: sweep_collisions(pts, ov, of, o[sub], d[sub], k[sub], r[sub], skin=skin),
                "trimesh ray_triangle",
                lambda: trimesh_sweep(pts, mesh, tri, o[sub], d[sub], k[sub], r[sub], skin),
                reps, baseline_repeats=1, unit="agree share", value=share,
            )
            row.note = f"max |diff| {worst:.3f}"
    if shapes_s:
        bench.note(
            "sweep",
            f"{len(shapes_s)} links: median Rust call {np.median(shapes_s) * 1e3:.1f} ms, "
            f"mean agreement {np.mean(agree_all):.3f}",
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="two shapes, fewer repeats")
    ap.add_argument("--shapes", default=",".join(SHAPES), help="PartNet-Mobility ids")
    ap.add_argument("--data", type=Path,
                    default=Path(os.environ.get("KINMO_DATA", REPO.parent / "shared" / "data")))
    ap.add_argument("--csv", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    ids = [s for s in args.shapes.split(",") if s]
    if args.quick:
        ids = ids[:2]
    bench = Bench(quick=args.quick, data=args.data)
    print(f"threads: {os.cpu_count()} cpus, RAYON_NUM_THREADS="
          f"{os.environ.get('RAYON_NUM_THREADS', '')}", file=sys.stderr)
    run(bench, ids)
    bench.report(args.csv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
