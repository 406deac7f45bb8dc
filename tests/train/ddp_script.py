"""Train one of kinmo's trainers on a tiny problem (for tests/train/test_distributed.py).

``python ddp_script.py TRAINER DATA OUT`` in one process, or the same under
``torch.distributed.run --nproc-per-node N``: the trainer itself joins the process group
(:mod:`kinmo.train.distributed`). TRAINER: ``ancsh`` (Laptop, supervised, DATA: PartNet-Mobility laptops) or ``axis``
(generated cabinets, DATA unused).
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
    elif trainer == "axis":
        from kinmo.refine.train import preset_config, train_axis_model
        from motion_cabinet import cabinet_graph

        graphs = [cabinet_graph(n_points=128, seed=s, jitter=0.2, shape_id=f"c{s}") for s in range(6)]
        net = {"n_points": 64, "k": 8, "widths": [8, 8, 16], "emb_dim": 16, "head": [16],
               "dropout": 0.0, "norm": "group"}
        cfg = preset_config("quick", epochs=3, batch_size=5, test_fraction=0.0, val_fraction=0.2,
                            net=net, device="cpu", category_min_objects=0, lr=3e-3)
        train_axis_model(graphs, out, cfg, progress=False)
    else:
        raise SystemExit(f"unknown trainer {trainer!r}")


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3]))
