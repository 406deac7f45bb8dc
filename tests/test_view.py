"""`kinmo view`: a self-contained page whose joint sliders move the parts, in headless Chromium:
a screenshot before and after moving a joint differs where the part is, and nowhere else."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy.ndimage import binary_dilation
from typer.testing import CliRunner

from browser import headless
from kinmo.cli import app
from kinmo.view import PLOT_HEIGHT, PLOT_WIDTH

OBJECT = "11700"  # dishwasher: the door (link 0) is a hinge on the static body (link 1)


def _shot(chromium: str, tmp: Path, url: str, name: str) -> np.ndarray:
    png = tmp / f"{name}.png"
    (tmp / name).mkdir()  # a fresh profile per shot (a reused one can show the previous page)
    res = headless(chromium, tmp / name, "--hide-scrollbars", f"--window-size={PLOT_WIDTH},{PLOT_HEIGHT}",
                   "--virtual-time-budget=15000", f"--screenshot={png}", url)
    assert png.is_file(), res.stderr[-2000:]
    return np.asarray(Image.open(png).convert("RGB")).astype(np.int16)


def _classes(img: np.ndarray) -> np.ndarray:
    """Per pixel: 0 background (white), 1 grey (static parts, black axes), 2.. hue bin."""
    hi, lo = img.max(axis=2), img.min(axis=2)
    sat = hi - lo
    hue = np.asarray(Image.fromarray(img.astype(np.uint8)).convert("HSV"))[..., 0].astype(int)
    out = np.where(sat >= 40, 2 + hue * 12 // 256, 1)
    return np.where((lo > 235) & (sat < 40), 0, out)


@pytest.mark.exactdata
def test_view_page_is_self_contained(mobility_root: Path, tmp_path: Path):
    out = tmp_path / "v.html"
    r = CliRunner().invoke(app, ["view", str(mobility_root / OBJECT), "--out", str(out)])
    assert r.exit_code == 0, r.output
    page = out.read_text()
    assert "kinmoView(" in page and "Plotly" in page
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=\"http", page)  # nothing fetched
    assert '"name":"joint_0"' in page


@pytest.mark.exactdata
def test_page_moves_links_as_mobility_v2_says(mobility_root: Path, tmp_path: Path, chromium: str):
    """The page's own kinematics (JavaScript) against kinmo.export.kinematics, for a hinge and
    a cylindrical joint (two sliders)."""
    import json
    import html as htmlmod

    from kinmo.data.readers import read_shape
    from kinmo.export.kinematics import link_poses

    for oid, hash_, values in (("11700", "joint_0=1.1", {0: 1.1}),
                               ("3596", "joint_1=0.05&joint_1_rotation=2.0", {1: (0.05, 2.0)})):
        out = tmp_path / f"{oid}.html"
        assert CliRunner().invoke(app, ["view", str(mobility_root / oid), "--out", str(out)]).exit_code == 0
        res = headless(chromium, tmp_path / oid, "--virtual-time-budget=15000", "--dump-dom",
                       out.as_uri() + "#" + hash_)
        m = re.search(r'data-poses="([^"]+)"', res.stdout)
        assert m, res.stderr[-2000:]
        got = json.loads(htmlmod.unescape(m.group(1)))
        want = link_poses(read_shape(mobility_root / oid).links, values)
        assert set(got) == {str(k) for k in want}
        for lid, T in want.items():
            np.testing.assert_allclose(np.array(got[str(lid)]["R"]).reshape(3, 3), T[:3, :3], atol=1e-9)
            np.testing.assert_allclose(got[str(lid)]["p"], T[:3, 3], atol=1e-9)
        assert any(not np.allclose(T, np.eye(4)) for T in want.values())


@pytest.mark.exactdata
def test_moving_a_joint_changes_the_view_only_where_the_part_is(
        mobility_root: Path, tmp_path: Path, chromium: str):
    out = tmp_path / "v.html"
    assert CliRunner().invoke(app, ["view", str(mobility_root / OBJECT), "--out", str(out)]).exit_code == 0
    url = out.as_uri()
    rest = _shot(chromium, tmp_path, url, "rest")
    moved = _shot(chromium, tmp_path, url + "#joint_0=1.2", "moved")
    alone0 = _shot(chromium, tmp_path, url + "#only=link_0", "alone0")
    alone1 = _shot(chromium, tmp_path, url + "#only=link_0&joint_0=1.2", "alone1")
    # compared as colour classes: WebGL shading of a static part shifts a little when another
    # part moves (Plotly lights the whole scene), its colour class does not
    diff = _classes(rest) != _classes(moved)
    part = (_classes(alone0) != 0) | (_classes(alone1) != 0)
    # the door moved: many pixels changed
    assert diff.sum() > 500, diff.sum()
    # and only where the door is (before or after), up to anti-aliasing at the edges
    outside = diff & ~binary_dilation(part, iterations=3)
    assert outside.sum() < 0.01 * diff.sum(), (outside.sum(), diff.sum())
    # the rest of the object is drawn (the body is visible and did not change)
    body = (_classes(rest) == 1) & ~binary_dilation(part, iterations=3)
    assert body.sum() > 500
