"""Benchmark ``kinmo render``: frames per second against PyBullet's ``getCameraImage`` alone.

For a few real objects (default: a refrigerator, a cabinet, a keyboard with 116 links, a
dishwasher with 51k faces, a bottle with a cylindrical joint) and each image size, in one
process (PyBullet DIRECT, CPU TinyRenderer):

- **baseline**: ``p.getCameraImage`` alone, same cameras (with the segmentation pass, or
  with ``ER_NO_SEGMENTATION_MASK``);
- **pipeline**: :func:`kinmo.render.dataset.render_frame` (joint state sampling, render,
  metric depth, back-projection, ANCSH ground truth), and the same plus the compressed
  ``.npz`` write (what ``kinmo render`` does per frame);
- **no-seg**: :meth:`Scene.render` without the segmentation pass + back-projection (no
  labels, so no ground truth): what skipping the pass would save.

Then the end-to-end :func:`~kinmo.render.dataset.render_dataset` throughput (URDF and mesh
loading included) with 1 and 2 worker processes. Numbers are frames per second and ratios to
the same-run baseline; the JSON goes to ``bench/results/bench_render.json``.

Usage::

    python bench/bench_render.py [--data DIR] [--frames 20] [--sizes 256 512] [--objects ID ...]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OBJECTS = ["10849", "46108", "7619", "11826", "3574"]


def _fps(n: int, seconds: float) -> float:
    return n / seconds if seconds > 0 else float("inf")


def bench_object(folder: Path, sizes: list[int], frames: int) -> list[dict]:
    import numpy as np
    import pybullet as p

    from kinmo.data.readers import read_shape
    from kinmo.render.ancsh_gt import link_meshes, rest_geometry
    from kinmo.render.camera import Camera, back_project
    from kinmo.render.dataset import RenderConfig, frame_rng, render_frame
    from kinmo.render.frames import save_frame as _save_frame
    from kinmo.render.scene import Scene

    shape = read_shape(folder)
    rows = []
    with Scene(shape) as scene:
        geometry = rest_geometry(scene.links, link_meshes(shape, scene.links), scene.frame_origins)
        n_faces = sum(len(f) for ms in link_meshes(shape, scene.links).values() for _, f in ms)
        for size in sizes:
            config = RenderConfig(width=size, height=size, seed=0)
            # cameras and states of the pipeline frames, replayed for the baselines
            views = []
            t0 = time.perf_counter()
            n_points = 0
            for f in range(frames):
                arrays, view = render_frame(scene, geometry, config, frame_rng(0, shape.id, f))
                n_points += len(arrays["points"])
                cam = Camera(size, size, config.fov_y, view["near"], view["far"],
                             arrays["cam_to_world"])
                state = {int(k): tuple(v) for k, v in view["state"].items()}
                views.append((cam, state))
            t_pipe = time.perf_counter() - t0
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                for f in range(frames):
                    arrays, view = render_frame(scene, geometry, config, frame_rng(0, shape.id, f))
                    _save_frame(Path(tmp) / f"{f:05d}.npz", arrays, {"view": view})
                t_save = time.perf_counter() - t0
                mb = sum(q.stat().st_size for q in Path(tmp).iterdir()) / frames / 1e6

            t_base = {True: 0.0, False: 0.0}
            t_noseg = 0.0
            for cam, state in views:
                scene.set_state(state)  # not timed
                for seg in (True, False):
                    flags = (p.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX if seg
                             else p.ER_NO_SEGMENTATION_MASK)
                    t0 = time.perf_counter()
                    p.getCameraImage(size, size, cam.view_matrix, cam.projection_matrix,
                                     renderer=p.ER_TINY_RENDERER, flags=flags,
                                     physicsClientId=scene.client)
                    t_base[seg] += time.perf_counter() - t0
                t0 = time.perf_counter()
                depth, _ = scene.render(cam, segmentation=False)
                back_project(depth, cam.K, np.isfinite(depth))
                t_noseg += time.perf_counter() - t0
            t_base_seg, t_base_noseg = t_base[True], t_base[False]
            row = {
                "object": shape.id, "category": shape.category, "faces": n_faces,
                "links": len(scene.links), "size": size, "frames": frames,
                "points_per_frame": n_points / frames, "npz_MB_per_frame": round(mb, 3),
                "fps_getCameraImage_seg": _fps(frames, t_base_seg),
                "fps_getCameraImage_noseg": _fps(frames, t_base_noseg),
                "fps_pipeline": _fps(frames, t_pipe),
                "fps_pipeline_with_write": _fps(frames, t_save),
                "fps_render_noseg_backproject": _fps(frames, t_noseg),
            }
            row["pipeline_vs_baseline"] = row["fps_pipeline"] / row["fps_getCameraImage_seg"]
            row["write_vs_baseline"] = row["fps_pipeline_with_write"] / row["fps_getCameraImage_seg"]
            row["seg_pass_cost"] = row["fps_getCameraImage_noseg"] / row["fps_getCameraImage_seg"]
            rows.append(row)
            print(f"{shape.id:>6} {shape.category:<16} {size:>4}px  getCameraImage "
                  f"{row['fps_getCameraImage_seg']:6.1f} fps (no seg {row['fps_getCameraImage_noseg']:6.1f})"
                  f"  pipeline {row['fps_pipeline']:6.1f} ({row['pipeline_vs_baseline']:.2f}x)"
                  f"  +write {row['fps_pipeline_with_write']:6.1f} ({row['write_vs_baseline']:.2f}x)"
                  f"  {row['points_per_frame']:.0f} pts, {mb:.2f} MB", flush=True)
    return rows


def bench_dataset(data: Path, objects: list[str], frames: int, size: int) -> list[dict]:
    from kinmo.render.dataset import RenderConfig, render_dataset

    out = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "objects"
        root.mkdir()
        for oid in objects:
            (root / oid).symlink_to(data / oid, target_is_directory=True)
        for workers in (1, 2):
            t0 = time.perf_counter()
            res = render_dataset(root, Path(tmp) / f"out{workers}", frames,
                                 RenderConfig(width=size, height=size), workers=workers,
                                 progress=False)
            dt = time.perf_counter() - t0
            n = res.count("ok")
            out.append({"workers": workers, "size": size, "frames": n, "seconds": dt,
                        "fps": _fps(n, dt)})
            print(f"render_dataset {len(objects)} objects x {frames} frames, {size}px, "
                  f"{workers} worker(s): {n} frames in {dt:.1f} s = {_fps(n, dt):.1f} fps", flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path,
                    default=Path(os.environ.get("KINMO_DATA", REPO.parent / "shared" / "data"))
                    / "partnet-mobility")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    ap.add_argument("--objects", nargs="+", default=DEFAULT_OBJECTS)
    args = ap.parse_args()

    rows = []
    for oid in args.objects:
        rows += bench_object(args.data / oid, args.sizes, args.frames)
    dataset = bench_dataset(args.data, args.objects, max(2, args.frames // 4), args.sizes[0])
    summary = {}
    for size in args.sizes:
        rs = [r for r in rows if r["size"] == size]
        tot = lambda k: len(rs) * args.frames / sum(args.frames / r[k] for r in rs)  # noqa: E731
        summary[size] = {k: tot(k) for k in ("fps_getCameraImage_seg", "fps_getCameraImage_noseg",
                                             "fps_pipeline", "fps_pipeline_with_write",
                                             "fps_render_noseg_backproject")}
        s = summary[size]
        print(f"all objects {size}px: getCameraImage {s['fps_getCameraImage_seg']:.1f} fps "
              f"(no seg {s['fps_getCameraImage_noseg']:.1f}), pipeline {s['fps_pipeline']:.1f} fps "
              f"= {s['fps_pipeline'] / s['fps_getCameraImage_seg']:.2f}x baseline, with write "
              f"{s['fps_pipeline_with_write']:.1f} fps = "
              f"{s['fps_pipeline_with_write'] / s['fps_getCameraImage_seg']:.2f}x")
    res_dir = REPO / "bench" / "results"
    res_dir.mkdir(parents=True, exist_ok=True)
    (res_dir / "bench_render.json").write_text(json.dumps(
        {"objects": rows, "summary": summary, "dataset": dataset}, indent=2))


if __name__ == "__main__":
    main()
