"""Foreign assets (issue 36): kinmo's bundle on articulated MuJoCo models from public
robot-learning repositories, given as the MJCF or URDF file and as a GLB with generic names
(:mod:`kinmo.evaluate.foreign`).

Build the assets first (``python bench/foreign_assets.py --out foreign/``; sources, commits
and licences in ``bench/foreign/sources.json``), then::

    python bench/bench_foreign.py --assets foreign/ --out OUT [--model runs/all/model]

``--model`` is a bundle folder (``kinmo train all`` writes ``OUT/model``)
pretrained model's name; default: kinmo's default pretrained model. Writes
``OUT/foreign.json`` (scores, per-object rows) and ``OUT/foreign.md``; prints the table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--assets", type=Path, required=True)
    ap.add_argument("--model", default=None)
    ap.add_argument("--out", type=Path, required=True, help="Work folder (staged objects, predictions).")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--variants", default="file,glb")
    ap.add_argument("--turn", type=int, default=0, choices=range(4),
                    help="GLBs turned this many quarter turns about their up axis (file variant left out).")
    ap.add_argument("--write-up", default="y", choices=("y", "z"),
                    help="GLBs written y-up or z-up, read without --up (file variant left out).")
    args = ap.parse_args(argv)

    from kinmo.evaluate.foreign import evaluate_foreign, foreign_markdown
    from kinmo.inference.predictor import Predictor
    from kinmo.pretrained import default_model

    bundle = Path(args.model) if args.model else default_model()
    predictor = Predictor.from_bundle(bundle, device=args.device)
    res = evaluate_foreign(args.assets, predictor, args.out, args.variants.split(","),
                           turn=args.turn, write_up=args.write_up)
    print(f"model: {bundle}")
    print(foreign_markdown(res))
    print(f"wrote {args.out / 'foreign.json'} and {args.out / 'foreign.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
