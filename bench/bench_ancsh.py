"""Benchmark ANCSH on partial scans: network inference and post-processing per frame.

On real rendered scans (default: a refrigerator and a two-door cabinet, rendered into a
temporary folder) this measures, in one process:

- **inference** (:func:`kinmo.ancsh.inference.predict_scans`: subsampling, normalisation,
  forward pass) per frame, for the ``quick`` and ``paper`` presets' network sizes (512 points
  / width 16 and 1024 points / width 64), with batches of 1 and of 16 frames; ratios: paper /
  quick, batch of 1 / batch of 16 (what batching saves), and the full network / its
  PointNet++ backbone alone (the cost of the heads);
- **post-processing** (:func:`kinmo.ancsh.postprocess.estimate`) per frame on perfect
  predictions (the targets as one-hot logits) and on an untrained network's output, with and
  without the joint-constrained refinement; ratios: refined / not refined, and
  post-processing / quick inference.

Seconds are medians over repeats. The JSON goes to ``bench/results/bench_ancsh.json``.
Run with one BLAS thread on shared machines (``OPENBLAS_NUM_THREADS=1``; the script sets it
when unset).

Usage::

    python bench/bench_ancsh.py [--data DIR] [--frames 6] [--repeats 3] [--threads 1] [--device cpu]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parents[1]
OBJECTS = {"Refrigerator": "10849", "StorageFurniture": "45463"}


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path(os.environ.get("KINMO_DATA", REPO.parent / "shared" / "data")))
    ap.add_argument("--frames", type=int, default=6, help="Scans per object.")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads.")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "bench_ancsh.json")
    args = ap.parse_args()

    import numpy as np
    import torch

    from kinmo.ancsh.config import preset
    from kinmo.ancsh.dataset import load_samples, normalize_points, scan_category, subsample_indices
    from kinmo.ancsh.evaluate import ground_truth_predictions
    from kinmo.ancsh.inference import build_model, predict_scans, quiet_estimate
    from kinmo.ancsh.scans import render_objects

    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    device = torch.device(args.device)
    mobility = args.data / "partnet-mobility"
    results: dict = {"device": str(device), "torch_threads": args.threads, "frames_per_object": args.frames,
                     "repeats": args.repeats, "objects": {}}
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-ancsh-") as tmp:
        for cat_name, oid in OBJECTS.items():
            cat = scan_category(mobility, cat_name)
            st = cat.structure
            cfg_r = preset("quick", render_workers=1, image_size=256)
            files, failed = render_objects({oid: cat.folders[oid]}, Path(tmp) / "o" / oid, Path(tmp) / "s",
                                           args.frames, cfg_r, progress=False)
            if failed:
                raise SystemExit(f"render failed: {failed}")
            samples, _ = load_samples(files, cat.parts, st, cache_points=None)
            scans = [s.points for s in samples]
            entry: dict = {"structure": st.signature(), "scans": len(scans),
                           "mean_points": float(np.mean([len(s) for s in scans]))}
            for name in ("quick", "paper"):
                cfg = preset(name)
                model = build_model(cfg, st).to(device).eval()
                predict_scans(model, scans[:2], cfg.n_points, device, batch_size=2)  # warm-up
                t1 = _median_time(lambda: predict_scans(model, scans, cfg.n_points, device, batch_size=1),
                                  args.repeats) / len(scans)
                tb = _median_time(lambda: predict_scans(model, scans, cfg.n_points, device, batch_size=16),
                                  args.repeats) / len(scans)
                xyz = torch.from_numpy(np.stack([normalize_points(s[subsample_indices(len(s), cfg.n_points,
                                                 np.random.default_rng(0))])[0] for s in scans])).to(device)
                with torch.no_grad():
                    tbb = _median_time(lambda: model.backbone(xyz), args.repeats) / len(scans)
                    tfull = _median_time(lambda: model(xyz), args.repeats) / len(scans)
                entry[f"inference_{name}"] = {"n_points": cfg.n_points, "width": cfg.width,
                                              "batch1_s": t1, "batch16_s": tb, "backbone_s": tbb,
                                              "forward_s": tfull}
                if name == "quick":
                    untrained = predict_scans(model, scans, cfg.n_points, device)
            perfect = []
            for s in samples:
                idx = subsample_indices(len(s), 512, np.random.default_rng(1))
                sub = type(s)(**{**s.__dict__, **{k: getattr(s, k)[idx] for k in (
                    "points", "seg", "npcs", "naocs", "heatmap", "unitvec", "axis", "joint", "position_mask")}})
                perfect.append((sub.points.astype(np.float64), ground_truth_predictions(sub, st)))
            for label, inputs in (("perfect", perfect), ("untrained", untrained)):
                for refine in (False, True):
                    def run():
                        for pts, pred in inputs:
                            quiet_estimate(pts, pred, st, refine=refine)
                    entry[f"post_{label}_{'refine' if refine else 'norefine'}_s"] = _median_time(
                        run, args.repeats) / len(inputs)
            q, p = entry["inference_quick"], entry["inference_paper"]
            entry["ratios"] = {
                "paper_over_quick_batch1": p["batch1_s"] / q["batch1_s"],
                "batch1_over_batch16_quick": q["batch1_s"] / q["batch16_s"],
                "batch1_over_batch16_paper": p["batch1_s"] / p["batch16_s"],
                "forward_over_backbone_quick": q["forward_s"] / q["backbone_s"],
                "forward_over_backbone_paper": p["forward_s"] / p["backbone_s"],
                "refine_over_norefine_perfect": entry["post_perfect_refine_s"] / entry["post_perfect_norefine_s"],
                "refine_over_norefine_untrained": entry["post_untrained_refine_s"] / entry["post_untrained_norefine_s"],
                "post_perfect_over_inference_quick": entry["post_perfect_refine_s"] / q["batch1_s"],
            }
            results["objects"][f"{cat_name}/{oid}"] = entry
            rows.append((f"{cat_name}/{oid}", entry))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")

    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"ANCSH per frame ({device}, {args.threads} torch thread(s))")
    t.add_column("measure")
    for name, _ in rows:
        t.add_column(name, justify="right")
    ms = lambda x: f"{1000 * x:.1f} ms"  # noqa: E731
    lines = [
        ("inference quick, batch 1", lambda e: ms(e["inference_quick"]["batch1_s"])),
        ("inference quick, batch 16", lambda e: ms(e["inference_quick"]["batch16_s"])),
        ("inference paper, batch 1", lambda e: ms(e["inference_paper"]["batch1_s"])),
        ("inference paper, batch 16", lambda e: ms(e["inference_paper"]["batch16_s"])),
        ("post-processing, perfect predictions", lambda e: ms(e["post_perfect_refine_s"])),
        ("  without refinement", lambda e: ms(e["post_perfect_norefine_s"])),
        ("post-processing, untrained network", lambda e: ms(e["post_untrained_refine_s"])),
        ("  without refinement", lambda e: ms(e["post_untrained_norefine_s"])),
    ] + [(k.replace("_", " "), (lambda k: lambda e: f"{e['ratios'][k]:.2f}x")(k)) for k in rows[0][1]["ratios"]]
    for label, f in lines:
        t.add_row(label, *(f(e) for _, e in rows))
    Console().print(t)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
