"""kinmo: kinematic motion prediction for 3D part hierarchies.

Predicts which parts of a PartNet / PartNet-Mobility object move, their joint type
(revolute, prismatic, both) and their axis, following Liu et al., *Semi-Weakly Supervised
Object Kinematic Motion Prediction*, CVPR 2023.

Submodules (imported on demand, so ``import kinmo`` stays light):

- :mod:`kinmo.geometry`: the Rust geometry core (sampling, OBB, contact adjacency,
  interaction regions, batched candidate motions).
- :mod:`kinmo.data`: dataset readers, ground-truth motion labels, part graphs, caches.
"""

from kinmo.errors import KinmoDataError, KinmoError

__version__ = "0.1.0"

__all__ = ["KinmoDataError", "KinmoError", "__version__"]
