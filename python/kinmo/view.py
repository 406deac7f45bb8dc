"""An interactive articulated viewer: a self-contained HTML page per object (``kinmo view``).

The page shows the object's meshes (one Plotly ``mesh3d`` trace per link, moving links in
colour, static ones grey), the predicted joint axes (solid) and the true ones (dashed, when a
labelled object is known), and a slider per degree of freedom (two for a cylindrical joint)
that moves the parts exactly as :mod:`kinmo.export.kinematics` does (rotation about /
translation along the axis from the rest pose, children carried by their parents; the same
transform the exporters and their tests use). Everything is inlined: Plotly's JavaScript, the
meshes and the kinematics (a few lines of JavaScript), so the page opens offline.

The joint values can also be set from the page address, ``page.html#joint_3=0.8&joint_1=0.2``
(radians / mesh units), and ``#only=link_3`` shows one link alone (used by the browser tests).

:func:`viewer_fragment` gives the ``<div>`` + data of one object for pages that embed several
viewers (the report's gallery), which include :func:`viewer_head` once.

Frames: mesh frame (y-up, the camera's up direction), mesh units; angles in radians.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.data.model import Link, Shape
from kinmo.data.names import clean_text
from kinmo.data.readers import read_links, read_shape
from kinmo.data.writers import write_mobility_v2
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.export.kinematics import link_meshes
from kinmo.io import write_text
from kinmo.urdf import urdf_joints

__all__ = ["PLOT_HEIGHT", "PLOT_WIDTH", "SOURCE_FILE", "gallery_page", "view_folder",
           "viewer_data", "viewer_fragment", "viewer_head", "write_view_links", "write_viewer"]

#: In a folder holding only ``mobility_v2.json`` (predicted links), the path of the shape
#: folder with the hierarchy and meshes they refer to.
SOURCE_FILE = "source.txt"

#: Size of the 3D view in CSS pixels (the sliders sit below it).
PLOT_WIDTH, PLOT_HEIGHT = 720, 540
#: Most triangles drawn per object (larger meshes keep an even subset of their faces).
MAX_FACES = 120_000
_COLORS = ("#e4572e", "#29335c", "#f3a712", "#669bbc", "#a8c686", "#8e44ad", "#17becf",
           "#d62728", "#2ca02c", "#ff7f0e")
_STATIC = "#b8b8b8"

_JS = r"""
function kinmoView(divId, data) {
  const div = document.getElementById(divId);
  const links = data.links, byId = {};
  links.forEach((l, i) => { l.index = i; byId[l.id] = l; });
  const vals = {};
  data.dofs.forEach(d => { vals[d.name] = 0; });
  const params = new URLSearchParams(window.location.hash.slice(1));
  data.dofs.forEach(d => { if (params.has(d.name)) vals[d.name] = parseFloat(params.get(d.name)); });
  const only = params.get('only');
  function rot(d, a) {  // Rodrigues, row-major 3x3
    const [x, y, z] = d, c = Math.cos(a), s = Math.sin(a), t = 1 - c;
    return [t*x*x + c, t*x*y - s*z, t*x*z + s*y,
            t*x*y + s*z, t*y*y + c, t*y*z - s*x,
            t*x*z - s*y, t*y*z + s*x, t*z*z + c];
  }
  function mul(A, B) {  // 3x4 affine [R|p] compose A∘B
    const R = [], p = [];
    for (let i = 0; i < 3; i++) {
      for (let j = 0; j < 3; j++) R[3*i+j] = A.R[3*i]*B.R[j] + A.R[3*i+1]*B.R[3+j] + A.R[3*i+2]*B.R[6+j];
      p[i] = A.R[3*i]*B.p[0] + A.R[3*i+1]*B.p[1] + A.R[3*i+2]*B.p[2] + A.p[i];
    }
    return {R: R, p: p};
  }
  function apply(T, v) {
    return [T.R[0]*v[0] + T.R[1]*v[1] + T.R[2]*v[2] + T.p[0],
            T.R[3]*v[0] + T.R[4]*v[1] + T.R[5]*v[2] + T.p[1],
            T.R[6]*v[0] + T.R[7]*v[1] + T.R[8]*v[2] + T.p[2]];
  }
  function poses() {
    const out = {};
    function pose(l) {
      if (out[l.id]) return out[l.id];
      let M = {R: [1,0,0, 0,1,0, 0,0,1], p: [0,0,0]};
      if (l.joint) {
        const t = vals[l.joint.t] || 0, a = vals[l.joint.r] || 0, d = l.joint.dir, o = l.joint.origin;
        const R = rot(d, a), Ro = apply({R: R, p: [0,0,0]}, o);
        M = {R: R, p: [o[0] - Ro[0] + t*d[0], o[1] - Ro[1] + t*d[1], o[2] - Ro[2] + t*d[2]]};
      }
      out[l.id] = l.parent in byId ? mul(pose(byId[l.parent]), M) : M;
      return out[l.id];
    }
    links.forEach(pose);
    return out;
  }
  const traces = links.map(l => ({type: 'mesh3d', name: l.name, x: l.x, y: l.y, z: l.z,
    i: l.i, j: l.j, k: l.k, color: l.color, flatshading: true, hoverinfo: 'name',
    visible: !only || only === 'link_' + l.id,
    lighting: {ambient: 0.55, diffuse: 0.8, specular: 0.05}}));
  data.axes.forEach(a => traces.push({type: 'scatter3d', mode: 'lines', name: a.label,
    x: [], y: [], z: [], hoverinfo: 'name', visible: !only,
    line: {color: a.kind === 'true' ? '#111111' : a.color, width: 6, dash: a.kind === 'true' ? 'dash' : 'solid'}}));
  function geometry() {
    const P = poses(), xs = [], ys = [], zs = [];
    div.setAttribute('data-poses', JSON.stringify(P));  // read back by the tests
    links.forEach(l => {
      const T = P[l.id], n = l.x.length, X = new Array(n), Y = new Array(n), Z = new Array(n);
      for (let q = 0; q < n; q++) {
        const v = apply(T, [l.x[q], l.y[q], l.z[q]]);
        X[q] = v[0]; Y[q] = v[1]; Z[q] = v[2];
      }
      xs.push(X); ys.push(Y); zs.push(Z);
    });
    data.axes.forEach(a => {
      const T = a.carrier in P ? P[a.carrier] : {R: [1,0,0, 0,1,0, 0,0,1], p: [0,0,0]};
      const h = a.length / 2, o = a.origin, d = a.dir;
      const p0 = apply(T, [o[0] - h*d[0], o[1] - h*d[1], o[2] - h*d[2]]);
      const p1 = apply(T, [o[0] + h*d[0], o[1] + h*d[1], o[2] + h*d[2]]);
      xs.push([p0[0], p1[0]]); ys.push([p0[1], p1[1]]); zs.push([p0[2], p1[2]]);
    });
    return {x: xs, y: ys, z: zs};
  }
  const g = geometry();
  traces.forEach((t, q) => { t.x = g.x[q]; t.y = g.y[q]; t.z = g.z[q]; });
  const layout = {width: data.width, height: data.height, margin: {l: 0, r: 0, t: 30, b: 0},
    title: {text: data.title, font: {size: 14}}, showlegend: false, paper_bgcolor: '#ffffff',
    scene: {aspectmode: 'cube', camera: {up: {x: 0, y: 1, z: 0}, eye: data.eye},
            xaxis: {visible: false, autorange: false, range: data.box[0]},
            yaxis: {visible: false, autorange: false, range: data.box[1]},
            zaxis: {visible: false, autorange: false, range: data.box[2]}}};
  Plotly.newPlot(div, traces, layout, {displaylogo: false, responsive: false}).then(() => {
    div.setAttribute('data-ready', '1');
  });
  const panel = document.getElementById(divId + '-sliders');
  data.dofs.forEach(d => {
    const row = document.createElement('label');
    row.className = 'kinmo-dof';
    const txt = document.createElement('span');
    const inp = document.createElement('input');
    Object.assign(inp, {type: 'range', min: d.lo, max: d.hi, step: (d.hi - d.lo) / 200, value: vals[d.name]});
    inp.id = divId + '-' + d.name;
    const show = () => { txt.textContent = d.label + ': ' + (d.unit === 'deg' ? (vals[d.name] * 180 / Math.PI).toFixed(1) + '°' : vals[d.name].toFixed(3)); };
    inp.addEventListener('input', () => {
      vals[d.name] = parseFloat(inp.value); show();
      const g = geometry();
      Plotly.restyle(div, g, traces.map((_, q) => q));
    });
    show();
    row.append(inp, txt);
    panel.append(row);
  });
}
"""

_CSS = """
.kinmo-viewer { font-family: system-ui, sans-serif; font-size: 13px; }
.kinmo-dof { display: flex; align-items: center; gap: 8px; margin: 2px 0; }
.kinmo-dof input { width: 260px; }
"""


def viewer_head() -> str:
    """``<script>``/``<style>`` a page needs once: Plotly (inlined) and the viewer code."""
    from plotly.offline import get_plotlyjs

    return (f"<script>{get_plotlyjs()}</script>\n<script>{_JS}</script>\n"
            f"<style>{_CSS}</style>\n")


def script_json(data: Any) -> str:
    """``data`` as JSON safe inside an HTML ``<script>`` block: ``<``, ``>``, ``&`` and the
    line separators U+2028/2029 as ``\\uXXXX`` escapes, so no name (``<!--``, ``</script``)
    can end or re-mode the block (issue 21, finding 10); control characters are JSON-escaped
    by :func:`json.dumps`."""
    s = json.dumps(data, separators=(",", ":"))
    for c, e in (("<", "\\u003c"), (">", "\\u003e"), ("&", "\\u0026"), ("\u2028", "\\u2028"),
                 ("\u2029", "\\u2029")):
        s = s.replace(c, e)
    return s


def _leaves(shape: Shape, link: Link) -> set[int]:
    return {leaf for pid in link.parts if pid in shape.hierarchy.nodes
            for leaf in shape.hierarchy.leaves(pid)}


def viewer_data(shape: Shape, links: Sequence[Link] | None = None,
                truth: Sequence[Link] | None = None, title: str | None = None,
                max_faces: int = MAX_FACES) -> dict:
    """The JSON-ready data of one viewer (meshes, degrees of freedom, axes).

    Parameters
    ----------
    shape : Shape
        Hierarchy and meshes.
    links : sequence of Link, optional
        The motion shown and moved (e.g. predicted); default ``shape.links``.
    truth : sequence of Link, optional
        True links: their axes are drawn dashed, carried by the shown link that holds most
        of their parts.
    title : str, optional
    max_faces : int
        Most triangles drawn (an even subset of each link's faces beyond).

    Returns
    -------
    dict
        ``links`` (rest vertices, faces, colour, joint), ``dofs`` (one slider each:
        ``joint_<id>`` and, for cylindrical joints, ``joint_<id>_rotation``; range from
        :func:`kinmo.urdf.urdf_joints`), ``axes``, ``eye``, ``width``, ``height``, ``title``.

    Raises
    ------
    KinmoDataError
        No links, inconsistent links, unreadable meshes.
    """
    import math

    links = list(shape.links or [] if links is None else links)
    if not links:
        raise KinmoDataError(shape.path, "nothing to view: no kinematic links")
    meshes = link_meshes(shape, links)
    total = sum(len(m.faces) for m in meshes.values())
    keep = max(1, math.ceil(total / max(1, max_faces)))
    allv = np.concatenate([m.vertices for m in meshes.values() if len(m.vertices)])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    joints = urdf_joints(links, shape.path)
    dofs, joint_of = [], {}
    for j in joints:
        if not j.is_moving:
            continue
        lo_, hi_ = (j.lower, j.upper) if j.lower is not None else (-math.pi, math.pi)
        rot = j.type != "prismatic"
        dofs.append({"name": j.name, "lo": lo_, "hi": hi_, "unit": "deg" if rot else "mesh",
                     "label": f"link_{j.link_id} {links_name(links, j.link_id)} "
                              f"({'rotation' if rot else 'translation'})"})
        e = joint_of.setdefault(j.link_id, {"t": None, "r": None})
        e["r" if rot else "t"] = j.name
    out_links, axes = [], []
    color_k = 0
    for l in sorted(links, key=lambda l: l.id):
        m = meshes[l.id]
        f = m.faces[::keep] if keep > 1 else m.faces
        moving = l.id in joint_of
        color = _COLORS[color_k % len(_COLORS)] if moving else _STATIC
        color_k += moving
        entry = {"id": l.id, "parent": l.parent, "name": f"link_{l.id} {l.name}",
                 "x": np.round(m.vertices[:, 0], 5).tolist(),
                 "y": np.round(m.vertices[:, 1], 5).tolist(),
                 "z": np.round(m.vertices[:, 2], 5).tolist(),
                 "i": f[:, 0].tolist(), "j": f[:, 1].tolist(), "k": f[:, 2].tolist(),
                 "color": color, "joint": None}
        if moving:
            d = np.asarray(l.joint.direction, float)
            d = d / np.linalg.norm(d)
            entry["joint"] = {"origin": np.asarray(l.joint.origin, float).tolist(),
                              "dir": d.tolist(), **joint_of[l.id]}
            axes.append({"kind": "pred", "label": f"predicted axis link_{l.id}", "color": color,
                         "origin": entry["joint"]["origin"], "dir": d.tolist(),
                         "length": 0.6 * size, "carrier": l.parent})
        out_links.append(entry)
    if truth:
        leaves = {l.id: _leaves(shape, l) for l in links}
        for t in truth:
            if t.parent == -1 or not t.joint.is_moving:
                continue
            tl = _leaves(shape, t)
            carrier = max(leaves, key=lambda k: len(leaves[k] & tl)) if leaves else -1
            parent_carrier = next((l.parent for l in links if l.id == carrier), -1)
            d = np.asarray(t.joint.direction, float)
            axes.append({"kind": "true", "label": f"true axis {t.name}", "color": "#111111",
                         "origin": np.asarray(t.joint.origin, float).tolist(),
                         "dir": (d / np.linalg.norm(d)).tolist(), "length": 0.6 * size,
                         "carrier": parent_carrier})
    return {"links": out_links, "dofs": dofs, "axes": axes, "title": title or shape.id,
            "eye": {"x": 0.62, "y": 0.45, "z": 0.8}, "width": PLOT_WIDTH, "height": PLOT_HEIGHT,
            # a fixed cube around the object that moving parts stay in (the view does not
            # re-frame when parts move or are hidden)
            "box": [[float(c - 0.7 * size), float(c + 0.7 * size)] for c in (lo + hi) / 2]}


def links_name(links: Sequence[Link], lid: int) -> str:
    """Name of link ``lid`` (``""`` if absent)."""
    return next((l.name for l in links if l.id == lid), "")


def viewer_fragment(data: dict, div_id: str) -> str:
    """The HTML of one viewer (plot ``<div>``, slider panel, data and the call)."""
    blob = script_json(data)
    return (f'<div class="kinmo-viewer"><div id="{html.escape(div_id)}" '
            f'style="width:{data["width"]}px;height:{data["height"]}px"></div>'
            f'<div id="{html.escape(div_id)}-sliders"></div></div>\n'
            f'<script>kinmoView({json.dumps(div_id)}, {blob});</script>\n')


def write_viewer(path: str | Path, data: dict) -> Path:
    """Write a self-contained viewer page (atomically) for ``data`` (:func:`viewer_data`)."""

    path = Path(path)
    page = ("<!doctype html>\n<html><head><meta charset=\"utf-8\">"
            f"<title>kinmo view: {html.escape(clean_text(data['title']))}</title>\n"
            "<style>body{margin:0}</style>\n" + viewer_head() + "</head><body>\n"
            + viewer_fragment(data, "kinmo-view")
            + "<p class=\"kinmo-viewer\" style=\"margin:6px\">coloured: moving parts; "
              "solid lines: predicted axes; dashed: true axes. Drag to turn the view.</p>"
            + "</body></html>\n")
    write_text(path, page)
    return path


def view_folder(folder: str | Path, out: str | Path | None = None,
                source: str | Path | None = None, truth: str | Path | None = None) -> Path:
    """Write the viewer page of a PartNet-Mobility folder (real, generated or predicted).

    Parameters
    ----------
    folder : str or Path
        A PartNet-Mobility folder, or a ``kinmo predict`` output folder (``mobility_v2.json``
        without meshes: give ``source``, or have it in ``FOLDER/source.txt``,
        :func:`write_view_links`).
    out : str or Path, optional
        The page; default ``FOLDER/view.html``.
    source : str or Path, optional
        The shape folder with the hierarchy and meshes that ``folder``'s links refer to
        (the input of ``kinmo predict``). Its own links, if any, are the true ones.
    truth : str or Path, optional
        A labelled PartNet-Mobility folder of the same shape: its axes are drawn dashed.

    Returns
    -------
    Path
        The page written.

    Raises
    ------
    KinmoDataError
        Unreadable folders, links naming parts missing from the hierarchy.
    """

    folder = Path(folder)
    truth_links = None
    if source is None and (folder / SOURCE_FILE).is_file():
        source = (folder / SOURCE_FILE).read_text(encoding="utf-8").strip()
    if source is None:
        shape = read_shape(folder)
        links = shape.links
    else:
        shape = read_shape(source)
        truth_links = shape.links
        links = read_links(folder / "mobility_v2.json", shape.hierarchy)
    if truth is not None:
        truth_links = read_shape(truth).links
    data = viewer_data(shape, links, truth_links, title=f"{shape.id} ({shape.category})")
    return write_viewer(Path(out) if out else folder / "view.html", data)


def write_view_links(folder: str | Path, links: Sequence[Link], source: str | Path) -> Path:
    """Write predicted ``links`` of the shape folder ``source`` for :func:`view_folder`.

    ``FOLDER/mobility_v2.json`` (part names from the source's hierarchy) and
    ``FOLDER/source.txt`` (the absolute source path); small, so every test shape of an
    evaluation can have one (the report's gallery viewer, :func:`gallery_page`).

    Returns
    -------
    Path
        ``folder``.

    Raises
    ------
    KinmoDataError
        ``source`` is not a readable shape folder, or the links are inconsistent.
    """

    folder = Path(folder)
    shape = read_shape(source)
    write_mobility_v2(links, folder / "mobility_v2.json", shape.hierarchy)
    write_text(folder / SOURCE_FILE, str(Path(source).resolve()) + "\n")
    return folder


def gallery_page(folders: Sequence[str | Path], path: str | Path, title: str = "kinmo viewer",
                 max_faces: int = 20_000) -> tuple[Path, list[str]]:
    """One page with a viewer per folder (Plotly inlined once), for the report's gallery.

    Parameters
    ----------
    folders : sequence of str or Path
        Folders :func:`view_folder` can read (e.g. from :func:`write_view_links`).
    path : str or Path
        The page, written atomically.
    title : str
    max_faces : int
        Triangles per object (keeps a page of tens of objects to a few tens of MB).

    Returns
    -------
    (Path, list of str)
        The page and, per folder that could not be shown, ``"<folder>: <reason>"``.
    """

    parts, problems = [], []
    for k, folder in enumerate(folders):
        folder = Path(folder)
        try:
            src = (folder / SOURCE_FILE).read_text(encoding="utf-8").strip()
            shape = read_shape(src)
            links = read_links(folder / "mobility_v2.json", shape.hierarchy)
            data = viewer_data(shape, links, shape.links,
                               title=f"{shape.id} ({shape.category})", max_faces=max_faces)
        except (KinmoError, OSError) as e:
            problems.append(f"{folder}: {' '.join(str(e).split())}")
            continue
        parts.append(viewer_fragment(data, f"kinmo-view-{k}"))
    page = ("<!doctype html>\n<html><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(clean_text(title))}</title>\n<style>body{{margin:8px}} "
            ".kinmo-viewer{display:inline-block;vertical-align:top;margin:6px}</style>\n"
            + viewer_head() + f"</head><body>\n<h2 class=\"kinmo-viewer\">{html.escape(clean_text(title))}</h2>"
            "<p class=\"kinmo-viewer\">coloured: moving parts; solid lines: predicted axes; "
            "dashed: true axes; a slider per joint.</p>\n" + "".join(parts) + "</body></html>\n")
    path = Path(path)
    write_text(path, page)
    return path, problems
