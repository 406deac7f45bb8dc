"""The pseudo-label rule graded on labelled objects (issue 34's "pseudo-labels looser").

``kinmo pseudo-label`` keeps a PartNet shape when every predicted moving joint scores at least
the threshold (:func:`kinmo.pseudo_label.score_joints`, :func:`kinmo.pseudo_label.judge`). The
unlabelled shapes have no motion to grade the kept labels against, so a change that loosens
the rule (more shapes kept, worse ones) is invisible in the pseudo-labelling run itself. This
module puts labelled objects the model did not train on (``kinmo train all``'s test split)
through the same prediction, refinement, scores and decision
(:func:`kinmo.pseudo_label.score_graph`), and grades every joint of the
kept objects against the truth:

- **kept**: objects kept / objects;
- **joint precision**: kept joints whose sibling edge truly moves;
- **type accuracy**: of those, the predicted motion (``R``, ``P``, ``PR``: the fine type's
  prefix) is the true one; **fine type accuracy**: the fine type itself;
- **axis error**: mean angle (degrees, sign-free) between the predicted and the true axis of
  the truly moving kept joints.

The same figures **per link** (``link_*``): a pseudo-label is a set of links
(``mobility_v2.json``), graded as Table 1 grades a mobility tree
(:func:`kinmo.evaluate.shape_metrics.match_joints`: each moving link's moved parts matched
one to one to a true moving link's, IoU >= 0.5). **Link precision**: matched / kept moving
links; **link type accuracy**: matched links of the true motion (``R``, ``P``, ``PR``);
**link axis error**: their mean angle. Per edge, a kept joint whose moving part truly moves
counts as a false one when its predicted reference is not the node the annotation's edge
names (a drawer moving relative to a table's back panel, a node that also holds other links'
parts, is labelled ``None``); per link it counts as the joint it is.

``kinmo train all`` grades the rule on its test split; ``kinmo eval oof`` grades it on every
labelled object, each with the models of the fold that held it out
(:func:`kinmo.evaluate.oof.oof_table1`, :meth:`PseudoRuleReport.extend`).

Issue 34's targets for the pseudo-labels of the shared PartNet shapes ("Done when"): joint
precision and type accuracy at least 0.95 and axis error at most 4° on the kept shapes, keeping
at least 60 % of the shapes; this grading on labelled objects is its stated check.

Outputs (:func:`write_pseudo_rule`): ``summary.json`` (every figure, per category too) and
``summary.md`` (one Markdown table).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_TYPES
from kinmo.evaluate.cells import cell
from kinmo.evaluate.shape_metrics import match_joints
from kinmo.io import write_json, write_text
from kinmo.metrics.axis import axis_angle_deg
from kinmo.metrics.motion_range import joint_kind
from kinmo.pseudo_label import PseudoLabelConfig, judge, score_graph

__all__ = ["JointGrade", "LinkGrade", "PseudoRuleReport", "grade_pseudo_rule", "summary_line",
           "write_pseudo_rule"]

_STILL = ("Fixed", "None")


@dataclass(frozen=True)
class JointGrade:
    """One scored joint of a labelled object.

    Attributes
    ----------
    shape_id, category : str
    kept : bool
        Its object passed the rule.
    score : float
        The pseudo-label score.
    moving : bool
        Its sibling edge truly moves.
    type_ok, fine_ok : bool
        Motion (``R``/``P``/``PR``) and fine type right (False when not moving).
    angle : float
        Axis error in degrees (NaN when not moving).
    """

    shape_id: str
    category: str
    kept: bool
    score: float
    moving: bool
    type_ok: bool
    fine_ok: bool
    angle: float


@dataclass(frozen=True)
class LinkGrade:
    """One predicted moving link of a labelled object (module docstring: per link).

    Attributes
    ----------
    shape_id, category : str
    kept : bool
        Its object passed the rule.
    matched : bool
        Its moved parts match a true moving link's (IoU >= 0.5, one to one).
    type_ok : bool
        Matched, with the true motion (``R``, ``P``, ``PR``).
    angle : float
        Axis error in degrees (sign-free) against the matched link; NaN when not matched.
    """

    shape_id: str
    category: str
    kept: bool
    matched: bool
    type_ok: bool
    angle: float


@dataclass
class PseudoRuleReport:
    """The graded rule (module docstring).

    Attributes
    ----------
    threshold : float
    n_objects : int
        Labelled objects graded.
    kept : list of str
        Ids of the kept objects.
    joints : list of JointGrade
        Every scored joint of every object (kept or not).
    links : list of LinkGrade
        Every predicted moving link of every object (kept or not).
    """

    threshold: float
    n_objects: int
    kept: list[str] = field(default_factory=list)
    joints: list[JointGrade] = field(default_factory=list)
    links: list[LinkGrade] = field(default_factory=list)

    def extend(self, other: PseudoRuleReport) -> None:
        """Add ``other``'s objects, kept ids, joints and links to this report (one report from
        several graded batches: the folds of ``kinmo eval oof``).

        Raises
        ------
        ValueError
            The two reports were graded at different thresholds.
        """
        if other.threshold != self.threshold:
            raise ValueError(f"threshold {other.threshold:g} is not this report's {self.threshold:g}")
        self.n_objects += other.n_objects
        self.kept += other.kept
        self.joints += other.joints
        self.links += other.links

    def summary(self, category: str | None = None) -> dict[str, float]:
        """Kept share and the kept joints' figures (module docstring), for every object or
        one category; NaN where there is nothing to average."""
        js = [j for j in self.joints if j.kept and (category is None or j.category == category)]
        mv = [j for j in js if j.moving]
        n = (self.n_objects if category is None
             else len({j.shape_id for j in self.joints if j.category == category}))
        kept = len({j.shape_id for j in js})

        def mean(x: list[float]) -> float:
            return float(np.mean(x)) if x else float("nan")

        ls = [lk for lk in self.links if lk.kept and (category is None or lk.category == category)]
        ml = [lk for lk in ls if lk.matched]
        return {"objects": float(n), "kept": float(kept), "kept_share": kept / n if n else float("nan"),
                "joints": float(len(js)), "joint_precision": mean([float(j.moving) for j in js]),
                "type_acc": mean([float(j.type_ok) for j in mv]),
                "fine_type_acc": mean([float(j.fine_ok) for j in mv]),
                "axis_mean_deg": mean([j.angle for j in mv]),
                "links": float(len(ls)), "link_precision": mean([float(lk.matched) for lk in ls]),
                "link_type_acc": mean([float(lk.type_ok) for lk in ml]),
                "link_axis_mean_deg": mean([lk.angle for lk in ml])}


def grade_pseudo_rule(predictor: Any, graphs: Sequence[PartGraph], config: PseudoLabelConfig,
                      meshes: Any = None, check: Any = None) -> PseudoRuleReport:
    """Put labelled graphs through the pseudo-label rule and grade it (module docstring).

    Parameters
    ----------
    predictor : kinmo.inference.predictor.Predictor
        The pseudo-labelling models (:meth:`~kinmo.inference.predictor.Predictor.from_parts`
        of the fine GNN run, the axis network and ``config.refine``, as ``kinmo
        pseudo-label`` loads them).
    graphs : sequence of PartGraph
        Labelled graphs the models did not train on; unlabelled ones are skipped.
    config : PseudoLabelConfig
        ``threshold``, ``score``, ``sign``, ``consistent``, ``hinge_limit``,
        ``slider_fraction``, ``agree_prob`` and ``agree_deg`` are used, as in
        :func:`kinmo.pseudo_label.pseudo_label_shape`.
    meshes : callable or None
        Per graph, its leaf meshes for the refinement's sweep
        (:meth:`~kinmo.inference.predictor.Predictor.refine_with_details`); None: read from
        each graph's source folder.
    check : kinmo.inference.predictor.Predictor or None
        The second model that must agree (``kinmo pseudo-label``'s ``check_run``), or None.

    Returns
    -------
    PseudoRuleReport
    """
    rep = PseudoRuleReport(float(config.threshold), 0)
    for g in graphs:
        if not g.has_labels or not len(g.sibling_edges):
            continue
        rep.n_objects += 1
        links, joints = score_graph(predictor, g, config, meshes=meshes, check=check)
        kept = judge(joints, config.threshold)[0] == "kept"
        if kept:
            rep.kept.append(g.shape_id)
        _, _, matches = match_joints(g, links)
        hit = {p.id: (joint_kind(p.joint) == joint_kind(t.joint),
                      float(axis_angle_deg(p.joint.direction, t.joint.direction)))
               for p, t, _ in matches}
        for lk in links:
            if lk.joint.is_moving:
                ok, angle = hit.get(lk.id, (False, float("nan")))
                rep.links.append(LinkGrade(g.shape_id, str(g.category), kept, lk.id in hit, ok, angle))
        by_id = {lk.id: lk for lk in links}
        ids = np.asarray(g.node_ids)
        edge_of = {(int(ids[i]), int(ids[j])): k for k, (i, j) in enumerate(g.sibling_edges)}
        for jd in joints:
            k = edge_of[(jd["moving_node"], jd["reference_node"])]  # the joint's sibling edge
            true = FINE_TYPES[int(g.edge_fine[k])]
            moving = true not in _STILL
            pred = str(jd["type"])
            d = by_id[jd["link"]].joint.direction
            angle = float(axis_angle_deg(d, g.edge_axis_direction[k])) if moving and d is not None else float("nan")
            rep.joints.append(JointGrade(
                g.shape_id, str(g.category), kept, float(jd["score"]), moving,
                moving and pred.split("_")[0] == true.split("_")[0], moving and pred == true, angle))
    return rep


def summary_line(s: Mapping[str, float | None]) -> str:
    """The kept objects' figures of :meth:`PseudoRuleReport.summary` (or of ``summary.json``'s
    ``all``, nulls included) as one line of text, as ``kinmo train all`` and ``kinmo eval oof``
    print them: ``K kept, joint precision P, type accuracy T (fine F), axis error A°; per link
    P, T, A°``."""
    return (f"{int(s['kept'])} kept, joint precision {cell(s['joint_precision'], 3)}, type accuracy "
            f"{cell(s['type_acc'], 3)} (fine {cell(s['fine_type_acc'], 3)}), axis error "
            f"{cell(s['axis_mean_deg'], 2)}°; per link {cell(s['link_precision'], 3)}, "
            f"{cell(s['link_type_acc'], 3)}, {cell(s['link_axis_mean_deg'], 2)}°")


def write_pseudo_rule(rep: PseudoRuleReport, out: str | Path) -> dict[str, Any]:
    """Write ``summary.json`` and ``summary.md`` into ``out`` (atomically).

    Returns
    -------
    dict
        The JSON document: ``threshold``, ``all`` (:meth:`PseudoRuleReport.summary`, NaN
        written as null) and ``categories`` (the same per category).
    """
    out = Path(out)
    cats = sorted({j.category for j in rep.joints})
    def clean(d: dict[str, float]) -> dict[str, float | None]:  # NaN is not JSON: null
        return {k: (None if v != v else v) for k, v in d.items()}

    doc = {"threshold": rep.threshold, "all": clean(rep.summary()),
           "categories": {c: clean(rep.summary(c)) for c in cats}}
    write_json(out / "summary.json", doc)

    head = ("| category | objects | kept | joint precision | type accuracy | fine type accuracy | "
            "axis error (°) | link precision | link type accuracy | link axis error (°) |\n"
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    rows = [(c.replace("|", "\\|"), doc["categories"][c]) for c in cats] + [("**all**", doc["all"])]
    body = "".join(f"| {c} | {int(s['objects'])} | {int(s['kept'])} | {cell(s['joint_precision'], 3)} | "
                   f"{cell(s['type_acc'], 3)} | {cell(s['fine_type_acc'], 3)} | {cell(s['axis_mean_deg'], 2)} | "
                   f"{cell(s['link_precision'], 3)} | {cell(s['link_type_acc'], 3)} | {cell(s['link_axis_mean_deg'], 2)} |\n"
                   for c, s in rows)
    write_text(out / "summary.md", f"Pseudo-label rule at {rep.threshold:g} on labelled objects\n\n" + head + body)
    return doc
