"""Dataset readers, ground-truth motion labels and part graphs.

- :mod:`kinmo.data.model`: the typed in-memory model (hierarchy, links, joints) and the
  paper's motion type vocabularies.
- :mod:`kinmo.data.graph`: :class:`~kinmo.data.graph.PartGraph`, the cached per-shape graph.
"""

from kinmo.data.graph import CACHE_VERSION, PartGraph
from kinmo.data.model import (
    COARSE_TYPES,
    FINE_TO_COARSE,
    FINE_TYPES,
    Joint,
    JointType,
    Link,
    PartHierarchy,
    PartNode,
    Shape,
    ShapeFormat,
)

__all__ = [
    "CACHE_VERSION",
    "COARSE_TYPES",
    "FINE_TO_COARSE",
    "FINE_TYPES",
    "Joint",
    "JointType",
    "Link",
    "PartGraph",
    "PartHierarchy",
    "PartNode",
    "Shape",
    "ShapeFormat",
]
