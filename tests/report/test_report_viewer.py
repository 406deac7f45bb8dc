"""The report's interactive gallery: an evaluation's predicted links of its test shapes become
viewer.html (one viewer per shape, Plotly inlined), linked from the gallery, drawn in Chromium."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from browser import headless
from kinmo.data.readers import read_shape
from kinmo.report import write_report
from kinmo.view import view_folder, write_view_links

OBJECTS = ["11700", "3596"]  # dishwasher (hinge), bottle (cylindrical)


@pytest.mark.exactdata
def test_report_writes_an_interactive_gallery(mobility_root: Path, tmp_path: Path, chromium: str):
    run = tmp_path / "run"
    for model in ("GNN_fine", "OBB_fine"):
        for oid in OBJECTS:
            shape = read_shape(mobility_root / oid)
            links = [dataclasses.replace(l, joint=dataclasses.replace(
                l.joint, direction=np.array([0.0, 0.0, 1.0]))) if l.joint.is_moving else l
                for l in shape.links]  # a "prediction": other axes than the true ones
            write_view_links(run / "eval" / "pre-segmented" / "viewers" / model / oid, links,
                             mobility_root / oid)
    # one such folder opens alone, too (source.txt names the meshes)
    assert view_folder(run / "eval" / "pre-segmented" / "viewers" / "GNN_fine" / "3596",
                       tmp_path / "one.html").is_file()
    res = write_report(run)
    page = res.out / "viewer.html"
    assert page.is_file()
    text = page.read_text()
    assert text.count("kinmoView(") == 1 + len(OBJECTS)  # the function + one call per shape
    assert "OBB_fine predictions" in text  # the refined model is preferred
    assert "true axis" in text and "predicted axis" in text
    assert "viewer.html" in res.html.read_text()
    dom = headless(chromium, tmp_path, "--virtual-time-budget=20000", "--dump-dom", page.as_uri())
    assert dom.returncode == 0, dom.stderr[-2000:]
    assert dom.stdout.count('data-ready="1"') == len(OBJECTS)  # every plot was drawn
    # a slider per degree of freedom: hinge 1, cylindrical 2
    assert dom.stdout.count('type="range"') == 3
