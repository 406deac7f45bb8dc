"""ANCSH learning curves on generated objects: training objects x training steps (issue 23).

Generates one kinematic structure with ``kinmo synth`` (default: laptops, one revolute joint,
exact ground truth): ``max(--objects)`` training objects (synth seed 1) and ``--test`` test
objects (synth seed 2, other ids), then for every cell of ``--objects`` x ``--epochs`` trains
ANCSH (``supervised``, the ``quick`` preset with ``epochs`` overridden: ``quick`` is 40 epochs
of 25 batches of 8, so 40 / 160 / 640 epochs are 1x / 4x / 16x its steps) on the first N
training objects and scores it on every scan of the test objects (``kinmo eval`` with
``--data`` the test folder). The training objects' renders are shared by the cells (one
cache), as are the test renders.

Per cell it records part rotation error (mean over frames of the mean over parts, and the
median), translation error, axis angle and distance, joint state error, the share of frames
with a rotation error above 30 degrees, and the training seconds. The table goes to
``OUT/curves.md`` and ``OUT/curves.json``. The results of issue 23 are in
``docs/results/ancsh_curves.md``.

Usage::

    nice -n 10 python bench/bench_ancsh_curves.py OUT [--category Laptop] [--structure 0<R-1] [--objects 4 16 64]
        [--epochs 40 160] [--test 8] [--width 16] [--threads 1]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def _split(path: Path, ids: list[str], category: str) -> Path:
    from kinmo.train.split import Split

    Split(train=ids, test=[], categories=dict.fromkeys(ids, category), seed=0, test_fraction=0.0).save(path)
    return path


def _frame_stats(frames_csv: Path) -> dict[str, float]:
    import numpy as np

    rows = list(csv.DictReader(frames_csv.open()))
    rot = np.array([[float(v) for k, v in r.items() if k.startswith("rotation_deg_")] for r in rows]).mean(1)
    return {"rotation_median": float(np.median(rot)), "rotation_over_30": float((rot > 30).mean())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--category", default="Laptop")
    ap.add_argument("--structure", default=None,
                    help="keep generated objects of this ANCSH structure only (kinmo synth --structure), "
                         "e.g. 0<R-1 for one-door refrigerators")
    ap.add_argument("--objects", type=int, nargs="+", default=[4, 16, 64])
    ap.add_argument("--epochs", type=int, nargs="+", default=[40, 160])
    ap.add_argument("--test", type=int, default=8)
    ap.add_argument("--width", type=int, default=16)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()

    from kinmo.ancsh.config import preset
    from kinmo.ancsh.evaluate import evaluate_category
    from kinmo.ancsh.objects import structure_filter
    from kinmo.ancsh.train import train_ancsh
    from kinmo.synth import generate_dataset

    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    train_dir, test_dir = out / "train", out / "test"
    keep = structure_filter(args.structure) if args.structure else None
    if not train_dir.is_dir():
        generate_dataset(train_dir, max(args.objects), seed=1, categories=[args.category], progress=False, keep=keep)
    if not test_dir.is_dir():
        generate_dataset(test_dir, args.test, seed=2, categories=[args.category], progress=False, keep=keep)
    ids = sorted(d.name for d in train_dir.iterdir() if d.is_dir())
    results = []
    for n in args.objects:
        split = _split(out / f"split{n}.json", ids[:n], args.category)
        for ep in args.epochs:
            name = f"n{n}_e{ep}_w{args.width}"
            run = out / "runs" / name
            cfg = preset("quick", epochs=ep, width=args.width, threads=args.threads, render_workers=1)
            t0 = time.perf_counter()
            train_ancsh(args.category, "supervised", run, cfg, data=train_dir, split=split,
                        scans=out / "scans_train", progress=False)
            seconds = time.perf_counter() - t0
            rows, paths = evaluate_category(args.category, [run], data=test_dir, out=run / "eval",
                                            scans=out / "scans_test", workers=1, progress=False)
            r = rows[0]
            cell = {"objects": n, "epochs": ep, "steps": ep * cfg.steps_per_epoch, "width": args.width,
                    "train_seconds": round(seconds, 1), "frames": r.frames,
                    **{m: float(r.mean(m)) for m in ("rotation_deg", "translation", "iou", "state",
                                                      "angle_deg", "distance")},
                    **_frame_stats(paths["frames"])}
            results.append(cell)
            print(json.dumps(cell), flush=True)
            (out / "curves.json").write_text(json.dumps(results, indent=1))
    lines = ["| objects | steps | width | rotation (deg, mean / median) | > 30 deg | translation | IoU "
             "| axis angle (deg) | axis distance | state (deg) | train s |", "|" + "---:|" * 11]
    for c in results:
        lines.append(f"| {c['objects']} | {c['steps']} | {c['width']} | {c['rotation_deg']:.2f} / "
                     f"{c['rotation_median']:.2f} | {100 * c['rotation_over_30']:.0f} % | {c['translation']:.4f} "
                     f"| {c['iou']:.3f} | {c['angle_deg']:.2f} | {c['distance']:.4f} | {c['state']:.2f} "
                     f"| {c['train_seconds']:.0f} |")
    (out / "curves.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
