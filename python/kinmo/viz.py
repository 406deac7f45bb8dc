"""PNG renders of motion predictions (matplotlib, Agg backend: no display needed).

:func:`render_prediction` draws a shape's leaf points, grey for the root link and one colour
per predicted moving link, the predicted joint axes as solid arrows in their link's colour
and the true axes (when the part graph has them) as dashed black arrows. The view keeps the
mesh frame's +y vertical (matplotlib's 3D ``z`` shows the mesh ``y``).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from kinmo.io import atomic_path

if TYPE_CHECKING:
    from kinmo.mobility_tree import ShapePrediction

__all__ = ["render_prediction"]

_BASE_GREY = (0.72, 0.72, 0.72, 0.35)


def _yup(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mesh (x, y, z) with y up -> matplotlib (x, z, y) so that y is drawn vertical."""
    p = np.asarray(p)
    return p[..., 0], p[..., 2], p[..., 1]


def render_prediction(pred: ShapePrediction, path: str | Path, points_per_leaf: int = 200,
                      max_points: int = 8000, show_truth: bool = True, dpi: int = 110,
                      elev: float = 20.0, azim: float = 60.0) -> Path:
    """Render one shape's predicted motion to a PNG file (written atomically).

    Parameters
    ----------
    pred : ShapePrediction
        Prediction of :func:`kinmo.predict.predict_graphs`.
    path : str or Path
        Output ``.png``.
    points_per_leaf : int
        Points drawn per leaf (the first ones of each leaf's samples).
    max_points : int
        Cap on all drawn points (leaves are thinned evenly beyond it).
    show_truth : bool
        Draw the true axes when the part graph has ground-truth links.
    dpi : int
    elev, azim : float
        Camera elevation and azimuth (degrees, matplotlib's convention on the drawn axes); the
        default looks at the front (+z of PartNet-Mobility objects) from the upper right.

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib import colormaps

    g = pred.graph
    tree = pred.tree
    leaves = np.flatnonzero(g.is_leaf)
    per = max(1, min(points_per_leaf, max_points // max(len(leaves), 1)))
    moving = [lk for lk in tree.links if lk.joint.is_moving]
    cmap = colormaps["tab10"]
    colour = {lk.id: cmap(k % 10) for k, lk in enumerate(moving)}
    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(111, projection="3d")
    for n in leaves:
        pts = np.asarray(g.points[n][:per], dtype=np.float64)
        c = colour.get(int(tree.leaf_link[n]), _BASE_GREY)
        x, y, z = _yup(pts)
        ax.scatter(x, y, z, s=1.5, color=c, depthshade=False)
    length = 0.35 * float(g.scale)
    for lk in moving:
        o, d = lk.joint.origin, lk.joint.direction
        x, y, z = _yup(o - 0.5 * length * d)
        u, v, w = _yup(length * d)
        ax.quiver(x, y, z, u, v, w, color=colour[lk.id], linewidth=2.5, arrow_length_ratio=0.15)
    if show_truth and g.meta.get("links"):
        for d in g.meta["links"]:
            if d.get("joint") not in ("hinge", "slider") or d.get("direction") is None:
                continue
            o, dr = np.asarray(d["origin"], float), np.asarray(d["direction"], float)
            dr = dr / np.linalg.norm(dr)
            x, y, z = _yup(o - 0.5 * length * dr)
            u, v, w = _yup(length * dr)
            ax.quiver(x, y, z, u, v, w, color="black", linestyle="dashed", linewidth=1.2,
                      arrow_length_ratio=0.1)
    allp = np.asarray(g.points[leaves][:, :per].reshape(-1, 3), dtype=np.float64)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    mid, r = (lo + hi) / 2, float(np.max(hi - lo)) / 2 * 1.1 + 1e-9
    mx, my, mz = _yup(mid)
    ax.set_xlim(mx - r, mx + r)
    ax.set_ylim(my - r, my + r)
    ax.set_zlim(mz - r, mz + r)
    ax.view_init(elev=elev, azim=azim)
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_zlabel("y (up)")
    names = ", ".join(f"{lk.name}:{lk.joint.type.value}{'+' if lk.joint.rotates else ''}"
                      for lk in moving) or "no moving part"
    ax.set_title(f"{g.shape_id} ({g.category})\n{names}\nsolid: predicted, dashed: true",
                 fontsize=8)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    plt.close(fig)
    return path
