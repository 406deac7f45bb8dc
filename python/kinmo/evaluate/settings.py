"""The four settings of the paper's Table 1 (Liu et al. 2023, Sec. 4.1) (moved from
``kinmo.refine.table``, issue 22: ``refine/`` stays below ``evaluate/``).

- ``GNN_coarse`` / ``GNN_fine``: the motion GNN trained on coarse (5) or fine (10) types,
  axes as regressed;
- ``OBB_coarse`` / ``OBB_fine``: the same predictions with every moving edge's axis refined
  (:meth:`kinmo.inference.predictor.Predictor.refine_prediction`).

All four are evaluated on the same labelled test graphs by
:func:`kinmo.evaluate.pre_segmented.evaluate_graphs` (edge-level type accuracy, angle error
and distance; joint-level detection, angle error and line distance), so the columns differ
only by the refinement.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_TYPES
from kinmo.evaluate.pre_segmented import evaluate_graphs
from kinmo.inference.gnn import predict_graphs
from kinmo.inference.predictor import Predictor
from kinmo.metrics.axis import axis_angle_deg, line_distance
from kinmo.refine.refine import RefineConfig

__all__ = ["FAILURE_KINDS", "PAPER_MEANS", "failure_kind", "failure_table", "four_settings"]

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

    preds: dict[str, list] = {}
    predictors = {kind: Predictor(run, axis_model, config or RefineConfig())  # one path: issue 22
                  for kind, run in (("coarse", coarse_run), ("fine", fine_run)) if run is not None}
    for kind, pr in predictors.items():
        preds[f"GNN_{kind}"] = predict_graphs(pr.run, graphs)
    for kind, pr in predictors.items():
        preds[f"OBB_{kind}"] = [pr.refine_prediction(p) for p in preds[f"GNN_{kind}"]]
    order = [m for m in ("GNN_coarse", "GNN_fine", "OBB_coarse", "OBB_fine") if m in preds]
    return evaluate_graphs(list(graphs), {m: preds[m] for m in order})


#: Failure kinds of a refined (or GNN) axis on a truly moving edge, in the order checked.
FAILURE_KINDS: tuple[str, ...] = ("orientation flip", "tilted box", "wrong parallel edge",
                                  "sign", "ok")


def failure_kind(direction, origin, true_direction, true_origin, scale: float, revolute: bool,
                 *, angle_deg: float = 5.0, distance: float = 0.05) -> str:
    """Classify one predicted axis against the truth (:data:`FAILURE_KINDS`).

    - ``orientation flip``: the line is more than 45° off (the 90° errors of a wrong H/V);
    - ``tilted box``: off by more than ``angle_deg`` but at most 45° (an OBB axis tilted from
      the hinge, a wrong diagonal);
    - ``wrong parallel edge``: direction right, a revolute line further than
      ``distance * scale`` from the true one (another of the box's parallel edges);
    - ``sign``: the line is right but its direction points against the true one (the part
      would open the wrong way);
    - ``ok``.

    Parameters
    ----------
    direction, origin, true_direction, true_origin : (3,) float
        Mesh frame.
    scale : float
        The shape's bounding-box diagonal.
    revolute : bool
        The true joint rotates (position matters).
    """
    import numpy as np

    a = float(axis_angle_deg(direction, true_direction))
    if a > 45.0:
        return "orientation flip"
    if a > angle_deg:
        return "tilted box"
    if revolute and float(line_distance(origin, direction, true_origin, true_direction)) > distance * scale:
        return "wrong parallel edge"
    if float(np.dot(direction, true_direction)) < 0:
        return "sign"
    return "ok"


def failure_table(predictions: dict[str, Sequence]) -> dict[str, dict[str, int]]:
    """Counts of :data:`FAILURE_KINDS` per model over the truly moving edges predicted moving.

    Parameters
    ----------
    predictions : dict of str to sequence of ShapePrediction
        Per model, predictions of labelled graphs (mesh frame).

    Returns
    -------
    dict of str to dict of str to int
    """
    import numpy as np

    out: dict[str, dict[str, int]] = {}
    for name, preds in predictions.items():
        counts = dict.fromkeys(FAILURE_KINDS, 0)
        for p in preds:
            g = p.graph
            lab = np.argmax(p.edges.probs, axis=1)
            for k in range(len(g.sibling_edges)):
                t_true = FINE_TYPES[int(g.edge_fine[k])]
                if t_true in ("Fixed", "None") or p.type_names[int(lab[k])] in ("Fixed", "None"):
                    continue
                counts[failure_kind(p.edges.direction[k], p.edges.origin[k],
                                    g.edge_axis_direction[k], g.edge_axis_origin[k],
                                    float(g.scale), not t_true.startswith("P_"))] += 1
        out[name] = counts
    return out
