"""Names and groups of the learned selector's per-candidate features (kinmo extension).

The column order of :func:`kinmo.refine.selector.candidate_features` and the names a
:class:`kinmo.refine.ranker.Ranker` stores, kept apart so that the feature computation
(:mod:`kinmo.refine.selector`) and the ranker (:mod:`kinmo.refine.ranker`) share them without
importing each other.
"""

from __future__ import annotations

__all__ = ["FEATURES", "FEATURE_GROUPS", "FEATURE_INDEX"]

#: Names of the per-candidate features, in column order of :func:`candidate_features`.
FEATURES: tuple[str, ...] = (
    "dir_prior", "log_dir_prior", "cos_gnn", "orient_prior", "pivot_prior", "pos_prior",
    "d_gnn", "attach_ref", "attach_any", "collide_min", "collide_max", "collide_rest",
    "feasibility", "kind_edge", "kind_center", "kind_interaction", "kind_axis", "kind_gnn",
    "frame_moving", "frame_reference", "frame_shape", "shape_aligned", "ref_aligned",
    "sweep_free_min", "sweep_free_max", "sweep_coll_min", "sweep_coll_max", "attach_mesh",
    "d_child", "d_child_edge",
    "sem_prior", "log_sem_prior",
    "ext_along", "thin_r_center", "thin_r_edge", "thin_p", "offset_r_center", "offset_r_edge",
    "offset_p",
)
#: Column index of each feature name in :data:`FEATURES`.
FEATURE_INDEX: dict[str, int] = {n: k for k, n in enumerate(FEATURES)}
#: Feature groups removed together in the ablation rows (``Ranker.drop``).
FEATURE_GROUPS: dict[str, tuple[str, ...]] = {
    "direction_prior": ("dir_prior", "log_dir_prior", "cos_gnn"),
    "orientation_prior": ("orient_prior",),
    "pivot_prior": ("pivot_prior",),
    "position_prior": ("pos_prior", "d_gnn"),
    "attachment": ("attach_ref", "attach_any", "attach_mesh"),
    "collision": ("collide_min", "collide_max", "collide_rest"),
    "sweep": ("sweep_free_min", "sweep_free_max", "sweep_coll_min", "sweep_coll_max"),
    "feasibility": ("feasibility",),
    "handle_side": ("d_child", "d_child_edge"),
    "semantic_prior": ("sem_prior", "log_sem_prior"),
    "part_shape": ("ext_along", "thin_r_center", "thin_r_edge", "thin_p", "offset_r_center",
                   "offset_r_edge", "offset_p"),
    "kind_frame": ("kind_edge", "kind_center", "kind_interaction", "kind_axis", "kind_gnn",
                   "frame_moving", "frame_reference", "frame_shape", "shape_aligned",
                   "ref_aligned"),
}
