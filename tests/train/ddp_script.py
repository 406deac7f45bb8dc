"""Train one of kinmo's trainers on a tiny problem (for tests/train/test_distributed.py).

``python ddp_script.py TRAINER DATA OUT`` in one process, or the same under
``torch.distributed.run --nproc-per-node N``: the trainer itself joins the process group
(:mod:`kinmo.train.distributed`). TRAINER: ``ancsh`` (Laptop, supervised) or ``axis``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch

torch.set_num_threads(1)


def main(trainer: str, data: Path, out: Path) -> None:
    if trainer == "ancsh":
        from kinmo.ancsh.config import preset
        from kinmo.ancsh.train import train_ancsh

        cfg = preset("quick", n_points=256, cache_points=1024, width=8, n_centers=(64, 16, 4),
                     image_size=96, batch_size=4, lr=3e-3, render_workers=1, threads=1,
                     schedule="constant", jitter=0.0, epochs=3, steps_per_epoch=3,
                     frames_per_object=3, test_fraction=0.3, device="cpu")
        train_ancsh("Laptop", "supervised", out, cfg, data=data, progress=False)
    else:
        raise SystemExit(f"unknown trainer {trainer!r}")


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3]))
