"""Prediction time with and without quarter turns for unnamed objects (issue 36,
:func:`kinmo.inference.gnn.infer_edges_with_priors`'s ``turns``).

The motion GNN predicts an object none of whose part names the model knows as the average
of its four quarter turns about the vertical (three more forward passes). This bench times
:func:`kinmo.predict.predict_dataset` (what ``kinmo predict DIR -j 1`` does: graphs,
GNN, refinement, ranges, ``mobility_v2.json``) over a folder of staged shapes with
``turns="never"`` and with the default ``"unnamed"``, alternating within each repeat, one
process, and prints the medians and their ratio. Staged unnamed shapes come from the foreign
bench (``python bench/bench_foreign.py --assets foreign/ --out OUT`` writes
``OUT/stage/glb/``, a node per part named ``part_<k>``)::

    python bench/bench_turns.py --data OUT/stage/glb [--model BUNDLE] [--repeats 3]

A folder of named shapes (PartNet) gives a ratio of 1: nothing is turned.
"""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="A folder of staged shapes.")
    ap.add_argument("--model", default=None, help="Bundle folder [default: the pretrained model].")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--device", default="cpu")
    args = ap.parse_args(argv)

    from kinmo.data.readers import find_shapes
    from kinmo.inference.predictor import Predictor
    from kinmo.predict import predict_dataset
    from kinmo.pretrained import default_model

    logging.disable(logging.WARNING)  # the range stage's per-part notes
    predictor = Predictor.from_bundle(Path(args.model) if args.model else default_model(), device=args.device)
    n = len(find_shapes(args.data))
    seconds: dict[str, list[float]] = {"never": [], "unnamed": []}
    load = os.getloadavg()[0]
    for _ in range(args.repeats):
        for turns in seconds:
            predictor.turns = turns  # type: ignore[assignment]
            out = Path(tempfile.mkdtemp(prefix="bench_turns_"))
            try:
                t0 = time.perf_counter()
                predict_dataset(args.data, predictor, out, progress=False, formats=["mobility_v2"])
                seconds[turns].append(time.perf_counter() - t0)
            finally:
                shutil.rmtree(out, ignore_errors=True)
    med = {k: statistics.median(v) for k, v in seconds.items()}
    print(f"shapes: {n}; repeats: {args.repeats}; 1-minute load average before / after: "
          f"{load:.2f} / {os.getloadavg()[0]:.2f}")
    print("| turns | wall s (median) | ms per shape | runs |")
    print("|---|---:|---:|---|")
    for k, v in seconds.items():
        runs = ", ".join(f"{x:.2f}" for x in v)
        print(f"| {k} | {med[k]:.2f} | {1000 * med[k] / max(n, 1):.1f} | {runs} |")
    print(f"ratio unnamed / never (medians): {med['unnamed'] / med['never']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
