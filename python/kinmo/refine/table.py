"""The four settings of the paper's Table 1 (Liu et al. 2023, Sec. 4.1).

- ``GNN_coarse`` / ``GNN_fine``: the motion GNN trained on coarse (5) or fine (10) types,
  axes as regressed;
- ``OBB_coarse`` / ``OBB_fine``: the same predictions with every moving edge's axis refined
  (:func:`kinmo.refine.refine.refine_shape_prediction`).

All four are evaluated on the same labelled test graphs by
:func:`kinmo.evaluate.pre_segmented.evaluate_graphs` (edge-level type accuracy, angle error
and distance; joint-level detection, angle error and line distance), so the columns differ
only by the refinement.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from kinmo.data.graph import PartGraph
from kinmo.refine.refine import RefineConfig, refine_shape_prediction

__all__ = ["PAPER_MEANS", "four_settings"]

#: Means of the paper's Table 1 quoted in kinmo's reports: axis angle error (degrees) and
#: distance of its four settings where known.
PAPER_MEANS: dict[str, dict[str, float]] = {
    "GNN_fine": {"angle": 8.93, "distance": 0.205},
    "GNN_coarse": {"angle": 12.23, "distance": 0.220},
    "OBB_fine": {"angle": 4.78, "distance": 0.112},
}


def four_settings(
    graphs: Sequence[PartGraph],
    fine_run: Any | None,
    coarse_run: Any | None,
    axis_model,
    config: RefineConfig | None = None,
) -> Any:
    """Evaluate GNN and refined (OBB) predictions of a fine and/or a coarse motion GNN.

    Parameters
    ----------
    graphs : sequence of PartGraph
        Labelled test graphs (the GNN runs' test split).
    fine_run, coarse_run : kinmo.train.gnn.Run or None
        Loaded runs (:func:`kinmo.train.gnn.load_run`); a missing one drops its two columns.
    axis_model : AxisSelectionNet
    config : RefineConfig, optional

    Returns
    -------
    kinmo.evaluate.pre_segmented.EvalReport
        Models ``GNN_coarse``, ``GNN_fine``, ``OBB_coarse``, ``OBB_fine`` (those available).
    """
    from kinmo.evaluate.pre_segmented import evaluate_graphs
    from kinmo.predict import predict_graphs

    preds: dict[str, list] = {}
    for kind, run in (("coarse", coarse_run), ("fine", fine_run)):
        if run is not None:
            preds[f"GNN_{kind}"] = predict_graphs(run, graphs)
    for kind in ("coarse", "fine"):
        if f"GNN_{kind}" in preds:
            preds[f"OBB_{kind}"] = [refine_shape_prediction(p, axis_model, config)[0]
                                    for p in preds[f"GNN_{kind}"]]
    order = [m for m in ("GNN_coarse", "GNN_fine", "OBB_coarse", "OBB_fine") if m in preds]
    return evaluate_graphs(list(graphs), {m: preds[m] for m in order})
