"""Motion refinement and axis selection (Liu et al. 2023, Sec. 3.3).

The motion GNN predicts, for every directed sibling edge ``(i, j)``, a motion type and an
axis. The refinement stage replaces the regressed axis by one of a few *candidate axes*
derived from the moving part's oriented bounding box (OBB) and from the interaction region
between the two parts, chosen by a score combining

- the *feasibility* of moving the part about / along the candidate, judged by a Siamese
  DGCNN on the point clouds before and after the candidate motion,
- the *agreement* of the candidate's direction and position with the GNN's axis.

Modules (one topic each):

- :mod:`kinmo.refine.candidates`: candidate axes from the OBB and the interaction region.
- :mod:`kinmo.refine.axis_net`: the axis-selection network (Siamese DGCNN).
- :mod:`kinmo.refine.motions`: network inputs, candidate motions and their amounts.
- :mod:`kinmo.refine.scoring`: feasibility / direction / position scores and selection.
- :mod:`kinmo.refine.train`: positive / negative motions from part-graph caches, training.
- :mod:`kinmo.refine.config`: the options of the refinement.
- :mod:`kinmo.refine.edge`: refine one edge (the paper's scoring or the learned selector).
- :mod:`kinmo.refine.refine`: refine the GNN's predictions of one shape (input contract, dispatch).
- :mod:`kinmo.refine.features`: names and groups of the learned selector's features.
- :mod:`kinmo.refine.selector`: the learned selector's candidates, GNN priors and features.
- :mod:`kinmo.refine.ranker`: the learned selector's calibrated listwise ranker.

Submodules are imported on demand (torch is heavy).
"""
