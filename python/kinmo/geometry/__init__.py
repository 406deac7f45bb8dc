"""The geometry core (Rust, :mod:`kinmo._core`) with numpy-friendly wrappers.

All functions take float64 arrays (points ``(N, 3)``) and integer faces ``(F, 3)``, check
shapes, finiteness and index ranges (``ValueError`` naming the argument), and run in Rust with
the GIL released. Frames are those of the input; PartNet objects are y-up.

- :mod:`kinmo.geometry.mesh`: OBJ loading.
- :mod:`kinmo.geometry.sampling`: area-weighted surface sampling.
- :mod:`kinmo.geometry.obb`: oriented bounding boxes.
- :mod:`kinmo.geometry.hull`: exact convex hulls.
- :mod:`kinmo.geometry.contact`: contact adjacency and mesh distances.
- :mod:`kinmo.geometry.decompose`: convex pieces of concave meshes (collision geometry).
- :mod:`kinmo.geometry.interaction`: interaction regions between two parts.
- :mod:`kinmo.geometry.motion`: batched candidate motions.
- :mod:`kinmo.geometry.sweep`: swept-collision feasibility and line-to-mesh distance.
- :mod:`kinmo.geometry.pointnet`: PointNet++ neighbourhoods (farthest point sampling, ball
  query, k nearest neighbours) of float32 point-cloud batches.
"""

from kinmo.geometry.contact import contact_pairs, mesh_distance
from kinmo.geometry.decompose import concave_pieces
from kinmo.geometry.hull import convex_hull
from kinmo.geometry.interaction import InteractionRegion, interaction_region
from kinmo.geometry.mesh import load_obj, load_objs
from kinmo.geometry.motion import apply_motions, motion_transforms
from kinmo.geometry.obb import OBB, fit_obb, fit_obb_batch
from kinmo.geometry.pointnet import ball_query, farthest_point_sample, k_nearest
from kinmo.geometry.sampling import sample_surface, sample_surface_groups
from kinmo.geometry.sweep import SweepObstacle, line_mesh_distance, sweep_collisions

__all__ = [
    "OBB",
    "InteractionRegion",
    "SweepObstacle",
    "apply_motions",
    "ball_query",
    "concave_pieces",
    "contact_pairs",
    "convex_hull",
    "farthest_point_sample",
    "fit_obb",
    "fit_obb_batch",
    "interaction_region",
    "k_nearest",
    "line_mesh_distance",
    "load_obj",
    "load_objs",
    "mesh_distance",
    "motion_transforms",
    "sample_surface",
    "sample_surface_groups",
    "sweep_collisions",
]
