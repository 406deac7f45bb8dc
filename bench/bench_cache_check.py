"""Benchmark the integrity check of cached part graphs (cache version 2).

``kinmo prepare`` decides that a shape is up to date by reading its ``.npz`` whole and
checking its arrays' checksum (:meth:`kinmo.data.graph.PartGraph.load`), where it used to
read only the metadata. On every ``.npz`` of a cache folder this measures, in one process:

- **meta only** (the old check, numpy): ``np.load`` of ``meta_json``, ``category``, ``format``;
- **numpy full read**: ``np.load`` of every array (the zip CRC of each member is checked);
- **kinmo**: :meth:`PartGraph.load` (every array, zip CRCs and the SHA-256 checksum).

Seconds are medians over the files of the best of ``--repeats`` passes (the files are in the
page cache after the first pass). Ratios: kinmo / numpy full read (the checksum's cost) and
kinmo / meta only (the cost of the stricter resume check per shape).

Usage::

    python bench/bench_cache_check.py CACHE [--repeats 3] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

from kinmo.data.graph import PartGraph


def meta_only(p: Path) -> None:
    with np.load(p, allow_pickle=False) as z:
        json.loads(str(z["meta_json"]))
        str(z["category"]), str(z["format"])


def full_read(p: Path) -> None:
    with np.load(p, allow_pickle=False) as z:
        for k in z.files:
            z[k]


def checked(p: Path) -> None:
    PartGraph.load(p)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cache", type=Path)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    files = sorted(a.cache.glob("*.npz"))
    if not files:
        raise SystemExit(f"{a.cache}: no .npz files")
    sides = {"meta_only": meta_only, "numpy_full_read": full_read, "kinmo_checked": checked}
    med: dict[str, float] = {}
    for name, fn in sides.items():
        best: list[float] | None = None
        for _ in range(a.repeats):
            times = []
            for p in files:
                t0 = time.perf_counter()
                fn(p)
                times.append(time.perf_counter() - t0)
            if best is None or sum(times) < sum(best):
                best = times
        med[name] = statistics.median(best or [0.0])
    res = {
        "files": len(files),
        "mb_median": statistics.median(p.stat().st_size for p in files) / 1e6,
        "median_s": med,
        "ratio_kinmo_vs_full_read": med["kinmo_checked"] / med["numpy_full_read"],
        "ratio_kinmo_vs_meta_only": med["kinmo_checked"] / med["meta_only"],
    }
    print(json.dumps(res, indent=2))
    if a.json:
        a.json.write_text(json.dumps(res, indent=2) + "\n")


if __name__ == "__main__":
    main()
