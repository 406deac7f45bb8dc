"""Charts of a run report as PNG bytes (matplotlib, Agg backend: no display needed).

- :func:`bar_chart`: grouped bars per category (one bar per model or setting), with the
  paper's reference means as a hatched ``paper`` group;
- :func:`curves_chart`: training curves of a ``metrics.csv`` (losses; accuracies, recalls and
  other scores in [0, 1]; errors), against the epoch;
- :func:`stacked_chart`: counts per category stacked by status (pseudo-labelling).
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

__all__ = ["BarPanel", "bar_chart", "curves_chart", "split_curves", "stacked_chart"]

_SCORE_WORDS = ("acc", "recall", "precision", "iou", "coverage", "chance", "f1")
_SKIP_SERIES = ("lr", "seconds", "time", "wall", "step", "iteration", "scans", "samples")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _png(fig) -> bytes:
    plt = _pyplot()
    buf = io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=100, metadata={"Software": "kinmo report"})
    finally:
        plt.close(fig)
    return buf.getvalue()


@dataclass
class BarPanel:
    """One panel of a grouped bar chart.

    Attributes
    ----------
    title : str
    groups : list of str
        The x-axis groups (categories, then ``mean``).
    series : dict of str to list of float
        One bar per group per series (model or setting); NaN leaves a gap.
    reference : dict of str to float
        Paper values per series name, drawn hatched in a final ``paper`` group.
    """

    title: str
    groups: list[str]
    series: dict[str, list[float]]
    reference: dict[str, float] = field(default_factory=dict)


def bar_chart(panels: Sequence[BarPanel], title: str = "", ncols: int = 2) -> bytes:
    """Grouped bar charts (one panel per metric) as PNG bytes.

    Parameters
    ----------
    panels : sequence of BarPanel
    title : str
    ncols : int
        Panels per row.

    Returns
    -------
    bytes
        A PNG image.
    """
    plt = _pyplot()
    from matplotlib import colormaps

    panels = list(panels)
    ncols = max(1, min(ncols, len(panels)))
    nrows = math.ceil(len(panels) / ncols)
    names: list[str] = []
    for p in panels:
        for n in [*p.series, *p.reference]:
            if n not in names:
                names.append(n)
    cmap = colormaps["tab10"]
    colour = {n: cmap(i % 10) for i, n in enumerate(names)}
    ngroups = max(len(p.groups) + (1 if p.reference else 0) for p in panels)
    fig, axes = plt.subplots(nrows, ncols, squeeze=False, layout="constrained",
                             figsize=(max(5.0, 0.55 * ngroups * max(1, len(names)) ** 0.5 + 2.5)
                                      * ncols, 3.4 * nrows + 0.6))
    for ax, p in zip(axes.flat, panels):
        groups = list(p.groups) + (["paper"] if p.reference else [])
        k = max(1, len(p.series))
        width = 0.8 / k
        for i, (name, vals) in enumerate(p.series.items()):
            pts = [(g + (i - (k - 1) / 2) * width, v) for g, v in enumerate(vals)
                   if v is not None and not math.isnan(v)]
            ax.bar([x for x, _ in pts], [y for _, y in pts], width * 0.95, color=colour[name],
                   label=name)
        refs = ([n for n in p.series if n in p.reference]
                + [n for n in p.reference if n not in p.series])
        rw = 0.8 / max(1, len(refs))
        for j, name in enumerate(refs):
            ax.bar(len(p.groups) + (j - (len(refs) - 1) / 2) * rw, p.reference[name], rw * 0.95,
                   color="white", edgecolor=colour[name], hatch="///", linewidth=1.2,
                   label="_paper" if name in p.series else f"{name} (paper only)")
        ax.set_xticks(range(len(groups)))
        ax.set_xticklabels(groups, rotation=30 if len(groups) > 5 else 0, ha="right"
                           if len(groups) > 5 else "center", fontsize=8)
        if "mean" in p.groups:
            ax.axvline(p.groups.index("mean") - 0.5, color="0.7", linewidth=0.8)
        ax.set_title(p.title, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        ax.set_axisbelow(True)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    if any(p.reference for p in panels):
        from matplotlib.patches import Patch

        handles.append(Patch(facecolor="white", edgecolor="0.3", hatch="///"))
        labels.append("paper (Liu et al. 2023)")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.legend(handles, labels, loc="outside lower center", ncol=min(len(labels), 5), fontsize=8,
               frameon=False)
    return _png(fig)


def split_curves(series: dict[str, list[float]]) -> dict[str, dict[str, list[float]]]:
    """Sort training series into panels: ``loss``, ``scores`` (accuracy, recall... in [0, 1])
    and ``errors`` (everything else numeric); learning rate and timings are left out."""
    out: dict[str, dict[str, list[float]]] = {"loss": {}, "scores": {}, "errors": {}}
    for name, vals in series.items():
        low = name.lower()
        if low in _SKIP_SERIES or low.endswith("_seconds") or low.endswith("_time"):
            continue
        if "loss" in low:
            out["loss"][name] = vals
        elif any(w in low for w in _SCORE_WORDS):
            out["scores"][name] = vals
        else:
            out["errors"][name] = vals
    return {k: v for k, v in out.items() if v}


def curves_chart(epochs: Sequence[float], series: dict[str, list[float]], title: str = "",
                 stages: Sequence[tuple[float, str]] = ()) -> bytes:
    """Training curves against the epoch as PNG bytes (panels of :func:`split_curves`).

    ``stages`` marks where training stages start (a dotted line and the stage's name) when
    there are several.

    Raises
    ------
    ValueError
        No series to plot.
    """
    panels = split_curves(series)
    if not panels:
        raise ValueError("no loss, score or error column to plot")
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 3.3), squeeze=False,
                             layout="constrained")
    ylabels = {"loss": "loss", "scores": "score", "errors": "error"}
    for ax, (kind, ser) in zip(axes.flat, panels.items()):
        for name, vals in ser.items():
            pts = [(e, v) for e, v in zip(epochs, vals) if not (math.isnan(e) or math.isnan(v))]
            if not pts:
                continue
            xs, ys = zip(*pts)
            style = "--" if name.lower().startswith(("test", "val")) else "-"
            ax.plot(xs, ys, style, marker="o" if len(xs) < 12 else None, markersize=3,
                    label=name, linewidth=1.4)
        if kind == "loss" and all(v > 0 for vals in ser.values() for v in vals
                                  if not math.isnan(v)):
            ax.set_yscale("log")
        if len(stages) > 1:
            for x, name in stages:
                ax.axvline(x - 0.5, color="0.5", linestyle=":", linewidth=1)
                ax.annotate(name, (x - 0.5, 1.0), xycoords=("data", "axes fraction"),
                            xytext=(3, -10), textcoords="offset points", fontsize=7,
                            color="0.35")
        ax.set_xlabel("epoch (stages in sequence)" if len(stages) > 1 else "epoch")
        ax.set_ylabel(ylabels[kind])
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    return _png(fig)


def stacked_chart(groups: Sequence[str], stacks: dict[str, list[float]], title: str = "",
                  xlabel: str = "shapes") -> bytes:
    """Horizontal bars per group, stacked by the keys of ``stacks``, as PNG bytes."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 0.45 * len(groups) + 1.6), layout="constrained")
    left = [0.0] * len(groups)
    colours = {"kept": "#2e8b57", "no_moving_joint": "#9aa5b1", "below_threshold": "#e0a030",
               "disagreement": "#8e6cc0",
               "failed": "#c0392b"}
    for i, (name, vals) in enumerate(stacks.items()):
        ax.barh(range(len(groups)), vals, left=left, label=name,
                color=colours.get(name, f"C{i}"))
        left = [a + b for a, b in zip(left, vals)]
    ax.set_yticks(range(len(groups)))
    ax.set_yticklabels(groups, fontsize=8)
    ax.invert_yaxis()
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel(xlabel)
    ax.grid(axis="x", alpha=0.3)
    ax.set_axisbelow(True)
    ax.legend(fontsize=8, ncol=min(4, len(stacks)), loc="lower center",
              bbox_to_anchor=(0.5, 1.0), frameon=False)
    if title:
        ax.set_title(title, fontsize=10, pad=24)
    return _png(fig)
