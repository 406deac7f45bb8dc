"""One predictor for every caller (issue 22): a model bundle loaded once, then a motion-GNN
prediction refined by the selector the bundle says, on any part graph.

``predict``, ``eval pre-segmented``, ``pseudo-label``, ``predict FILE``
(:mod:`kinmo.user_input`) and the pipeline build a :class:`Predictor` (from a bundle folder,
:meth:`Predictor.from_bundle`, or from parts already loaded, :meth:`Predictor.from_parts`)
and call :meth:`Predictor.predict`. The rule of which selector is used lives here only:

- ``"ranker"`` (the default when the bundle has a ranker): the learned selector (kinmo
  extension, :mod:`kinmo.refine.selector`); it needs no axis network.
- ``"paper"``: the paper's 0.5 / 0.3 / 0.2 scoring with the axis-selection network (Liu et
  al. 2023, Sec. 3.3); the ablation switch (``--paper-selector``).
- ``"none"``: the GNN's axes as predicted.

Ranges (issue 35): with a range prior (the bundle's ``ranges.json``, or
``RefineConfig.ranges``), every predicted moving joint gets a learned range clipped by a sweep
of its part (:func:`kinmo.ranges.predict_ranges`), after the selector; without one the tree's
default ranges (:class:`~kinmo.mobility_tree.TreeOptions`) stay.

Meshes: the learned selector's sweep features and the range sweep need the shape's leaf
meshes. A caller that has them passes them (:class:`kinmo.refine.selector.ShapeMeshes`, or a callable returning
them); otherwise they are read from the graph's source folder, and when that fails a
warning names the shape (never a silent fallback).

Frames: everything in the graph's mesh frame (PartNet is y-up), mesh units.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

from kinmo.data.graph import PartGraph
from kinmo.errors import KinmoDataError
from kinmo.inference.bundle import ModelBundle, resolve_bundle
from kinmo.inference.gnn import TurnPolicy, predict_graphs
from kinmo.mobility_tree import ShapePrediction, TreeOptions
from kinmo.ranges import RangePrior, predict_ranges
from kinmo.refine.axis_io import load_axis_model
from kinmo.refine.config import RefineConfig
from kinmo.refine.ranker import load_ranker
from kinmo.refine.refine import RefinedPredictions, ranker_needs_meshes, refine_shape_prediction
from kinmo.refine.selector import ShapeMeshes, shape_meshes
from kinmo.train.gnn import Run, load_run

__all__ = ["MeshSource", "Predictor", "SelectorName"]

logger = logging.getLogger(__name__)

SelectorName = Literal["auto", "ranker", "paper", "none"]
#: What :meth:`Predictor.predict` accepts as meshes: the meshes, or a callable giving them.
MeshSource = ShapeMeshes | Callable[[PartGraph], ShapeMeshes | None] | None


def _has_net(axis: Path) -> bool:
    """True when ``axis`` is an axis network: a checkpoint file or a folder with ``model.pt``."""
    return (axis.is_file() and axis.suffix == ".pt") or (axis / "model.pt").is_file()


def _axis_device(run: Run) -> str:
    return "cpu" if run.device.type == "cpu" else str(run.device)


@dataclass
class Predictor:
    """A loaded model: motion GNN, optional axis network, refinement configuration.

    Attributes
    ----------
    run : Run
        The motion GNN (:func:`kinmo.train.gnn.load_run`).
    axis_net : AxisSelectionNet or None
        The axis-selection network (paper selector only).
    refine : RefineConfig or None
        The refinement; None: the GNN's axes as predicted.
    options : TreeOptions
        Limits of the mobility tree.
    bundle : ModelBundle or None
        Where the parts came from.
    ranges : RangePrior or None
        The range-of-motion prior (issue 35); None: the default ranges of ``options``.
    turns : {"unnamed", "always", "never"}
        Which objects the GNN predicts as the average of their four quarter turns about the
        vertical (:func:`kinmo.inference.gnn.infer_edges_with_priors`; issue 36): by default
        those without a part name the model knows.
    """

    run: Run
    axis_net: Any = None
    refine: RefineConfig | None = None
    options: TreeOptions = TreeOptions()
    bundle: ModelBundle | None = None
    ranges: RangePrior | None = None
    turns: TurnPolicy = "unnamed"

    @classmethod
    def from_parts(cls, run: str | Path | Run, axis_model: str | Path | None = None,
                   refine_config: RefineConfig | None = None, options: TreeOptions = TreeOptions(),
                   device: str = "auto") -> Predictor:
        """A predictor from a GNN run (folder or loaded), an optional axis network and a
        refinement configuration, as the commands got them before bundles.

        The axis network is loaded only when the configuration needs it (the paper
        selector); the learned selector (``refine_config.selector == "ranker"``) uses it
        only when its weights are present. Without ``axis_model`` no refinement is done.
        ``refine_config.ranges`` names the range prior, loaded here once.

        Raises
        ------
        KinmoDataError
            A model cannot be loaded; the paper selector without an axis network.
        """
        r = run if isinstance(run, Run) else load_run(run, device)
        cfg = refine_config or RefineConfig()
        ranges = RangePrior.load(cfg.ranges) if cfg.ranges else None
        if axis_model is None:
            if refine_config is not None and cfg.selector == "ranker":
                return cls(r, None, cfg, options, ranges=ranges)  # the learned selector needs no network
            return cls(r, None, None, options, ranges=ranges)
        axis = Path(axis_model)
        has_net = _has_net(axis)
        if cfg.selector != "ranker" and not has_net:
            raise KinmoDataError(axis / "model.pt", "no axis network for the paper's scoring; give "
                                 "a run of `kinmo train axis` or a ranker")
        net = load_axis_model(axis, _axis_device(r)) if has_net else None
        return cls(r, net, cfg, options, ranges=ranges)

    def with_gnn(self, run: str | Path | Run, device: str = "auto") -> Predictor:
        """This predictor's refinement (axis network, selector, range prior, options) with
        another motion-GNN run (folder or loaded): a second model judged like the first
        (:func:`kinmo.pseudo_label.score_graph`'s ``check``), its shared parts not loaded
        again.

        Raises
        ------
        KinmoDataError
            The run cannot be loaded.
        """
        return replace(self, run=run if isinstance(run, Run) else load_run(run, device), bundle=None)

    @classmethod
    def from_bundle(cls, model: str | Path, device: str = "auto", selector: SelectorName = "auto",
                    axis_model: str | Path | None = None, ranker: str | Path | None = None,
                    refine_config: RefineConfig | None = None,
                    options: TreeOptions = TreeOptions()) -> Predictor:
        """Load a model bundle (or a GNN run, :func:`kinmo.inference.bundle.resolve_bundle`).

        Parameters
        ----------
        model : str or Path
            Bundle folder, or GNN run folder / ``model.pt``.
        device : str
        selector : {"auto", "ranker", "paper", "none"}
            ``auto``: the learned selector when a ranker is present, else the paper's with
            an axis network, else none.
        axis_model, ranker : str or Path, optional
            Override the bundle's parts.
        refine_config : RefineConfig, optional
            Base options (e.g. of the command line); its ``selector``/``ranker`` are set here.
        options : TreeOptions

        Raises
        ------
        KinmoDataError
            A part is missing or unreadable, or the selector asked for is not available.
        """
        b = resolve_bundle(model, axis_model, ranker)
        if selector == "auto":
            selector = "ranker" if b.ranker is not None else ("paper" if b.has_axis_network else "none")
        if selector == "ranker" and b.ranker is None:
            raise KinmoDataError(b.root or b.gnn, "no ranker.json for the learned selector")
        if selector == "paper" and not b.has_axis_network:
            raise KinmoDataError(b.root or b.gnn, "no axis network for the paper's selector")
        base = refine_config or RefineConfig()
        if b.ranges is not None and base.ranges is None:
            base = base.model_copy(update={"ranges": str(b.ranges)})
        if selector == "none":
            p = cls.from_parts(b.gnn, None, RefineConfig(ranges=base.ranges), options, device)
        else:
            extra = ({"selector": "ranker", "ranker": str(b.ranker)} if selector == "ranker"
                     else {"selector": "paper", "ranker": None})
            cfg = base.model_copy(update=extra)
            p = cls.from_parts(b.gnn, b.axis if b.has_axis_network else None, cfg, options, device)
        p.bundle = b
        return p

    @property
    def selector(self) -> str:
        """``"ranker"``, ``"paper"`` or ``"none"``."""
        return "none" if self.refine is None else self.refine.selector

    @property
    def source(self) -> Path:
        """The model's folder: the bundle's (or its GNN's), else the GNN run's."""
        return (self.bundle.root or self.bundle.gnn) if self.bundle is not None else self.run.path

    def describe(self) -> str:
        """One line: which model and selector are used."""
        src = self.source
        sel = {"ranker": f"learned selector ({self.refine.ranker})" if self.refine else "",
               "paper": "paper selector (0.5/0.3/0.2, axis network)",
               "none": "no refinement (GNN axes)"}[self.selector]
        return f"model {src}: motion GNN + {sel}"

    def _ranker_meshes(self) -> bool:
        return (self.refine is not None and self.refine.selector == "ranker"
                and ranker_needs_meshes(load_ranker(str(self.refine.ranker))))

    def _meshes(self, graph: PartGraph, meshes: MeshSource,
                ranker_needs: bool | None = None) -> ShapeMeshes | None:
        """The shape's meshes when the ranker's sweep features (``ranker_needs``, by default
        asked of the ranker) or the range sweep need them; a missing mesh is logged once, by
        whichever needs it (:func:`kinmo.ranges.predict_ranges` logs its own)."""
        if ranker_needs is None:
            ranker_needs = self._ranker_meshes()
        if not ranker_needs and self.ranges is None:
            return None
        m = meshes(graph) if callable(meshes) else meshes
        if m is None:
            m = shape_meshes(graph)
        if m is None and ranker_needs:
            logger.warning("%s: no meshes (source %s unreadable or not matching the graph): the "
                           "ranker's sweep features use the point proxy", graph.shape_id,
                           graph.meta.get("source", "unknown"))
        return m

    def refine_with_details(self, pred: ShapePrediction, meshes: MeshSource = None,
                            options: TreeOptions | None = None
                            ) -> tuple[ShapePrediction, RefinedPredictions | None]:
        """The selector's refinement of a GNN prediction (:func:`kinmo.inference.gnn.predict_graphs`
        of this predictor's run), its mobility tree rebuilt and its joints given ranges (with a
        range prior), with the per-edge details
        (:class:`~kinmo.refine.refine.RefinedPredictions`; None without a refinement)."""
        ranker_needs = self._ranker_meshes()
        m = self._meshes(pred.graph, meshes, ranker_needs)
        det = None
        if self.refine is not None:
            pred, det = refine_shape_prediction(pred, self.axis_net, self.refine, options or self.options,
                                                meshes=m if ranker_needs else None)
        if self.ranges is not None:
            pred = predict_ranges(pred, self.ranges, m, seed=self.refine.seed if self.refine else 0)
        return pred, det

    def refine_prediction(self, pred: ShapePrediction, meshes: MeshSource = None) -> ShapePrediction:
        """:meth:`refine_with_details` without the details."""
        return self.refine_with_details(pred, meshes)[0]

    def gnn_predictions(self, graphs: list[PartGraph], options: TreeOptions | None = None,
                        consistent: bool = True, batch_size: int = 8) -> list[ShapePrediction]:
        """The motion GNN's predictions of part graphs, before refinement
        (:func:`kinmo.inference.gnn.predict_graphs` of this predictor's run; ``options``:
        this predictor's by default), for :meth:`refine_with_details`."""
        return predict_graphs(self.run, graphs, options or self.options, batch_size,
                              consistent=consistent, turns=self.turns)

    def predict_many(self, graphs: list[PartGraph], meshes: MeshSource = None,
                     batch_size: int = 8) -> list[ShapePrediction]:
        """:meth:`predict` of several graphs, the GNN batched."""
        preds = self.gnn_predictions(graphs, batch_size=batch_size)
        return [self.refine_prediction(p, meshes) for p in preds]

    def predict(self, graph: PartGraph, meshes: MeshSource = None) -> ShapePrediction:
        """Predict one shape: GNN, then the selector's refinement, then the mobility tree.

        Parameters
        ----------
        graph : PartGraph
            Labels, if present, are ignored.
        meshes : ShapeMeshes or callable, optional
            The shape's leaf meshes (mesh frame) or a source of them; by default read from
            the graph's source folder, with a warning when that fails.

        Returns
        -------
        ShapePrediction
            Mesh frame.
        """
        return self.predict_many([graph], meshes)[0]
