"""Dataset readers, ground-truth motion labels and part graphs.

- :mod:`kinmo.data.model`: the typed in-memory model (hierarchy, links, joints) and the
  paper's motion type vocabularies.
- :mod:`kinmo.data.graph`: :class:`~kinmo.data.graph.PartGraph`, the cached per-shape graph.
- :mod:`kinmo.data.readers`: PartNet / PartNet-Mobility folders -> :class:`Shape`.
- :mod:`kinmo.data.labels`: ground-truth fine motion types and axes of sibling edges.
- :mod:`kinmo.data.build`: :func:`build_graph`, a shape's part graph (Rust geometry core).
"""

from kinmo.data.build import build_graph
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
from kinmo.data.readers import detect_format, find_shapes, read_shape

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
    "build_graph",
    "detect_format",
    "find_shapes",
    "read_shape",
]
