"""``kinmo report RUN``: HTML + Markdown reports of pipeline runs (kinmo.report)."""

from __future__ import annotations

import base64
import math
import re
import shutil
from html.parser import HTMLParser

import pytest
from typer.testing import CliRunner

from kinmo.cli import app
from browser import headless, images_loaded
from .report_fake_run import (
    TABLE2,
    make_run,
    table2_means,
    write_gnn_metrics,
    write_png,
    write_table1,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class _Page(HTMLParser):
    """Tables (rows of cell texts), images (attributes) and external references of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[list[list[str]]] = []
        self.images: list[dict[str, str]] = []
        self.external: list[str] = []
        self._cell: list[str] | None = None
        self._row: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "img":
            self.images.append(a)
        if tag in ("script", "link", "iframe") and (a.get("src") or a.get("href")):
            self.external.append(a.get("src") or a.get("href"))

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.tables[-1].append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def parse(html: str) -> _Page:
    p = _Page()
    p.feed(html)
    return p


def row_starting(page: _Page, first: str) -> list[list[str]]:
    """Every table row whose first cell is ``first``."""
    return [r for t in page.tables for r in t if r and r[0] == first]


def f(v: float, decimals: int) -> str:
    """A metric as the report shows it: read back from the CSV (6 significant digits)."""
    return f"{float(f'{v:.6g}'):.{decimals}f}"


def invoke(*args: str):
    return CliRunner().invoke(app, ["report", *map(str, args)])


@pytest.fixture(scope="module")
def full(tmp_path_factory):
    """A whole fake pipeline run and its report (default output folder RUN/report)."""
    root = tmp_path_factory.mktemp("report") / "run"
    info = make_run(root)
    res = invoke(root)
    assert res.exit_code == 0, res.output
    out = root / "report"
    html = (out / "index.html").read_text(encoding="utf-8")
    return {"root": root, "out": out, "info": info, "output": res.output, "html": html,
            "page": parse(html), "md": (out / "report.md").read_text(encoding="utf-8")}


def test_table1_next_to_paper(full):
    """The evaluation's means and the paper's Table 1 means sit in the same rows."""
    rep = full["info"]["table1"]
    page = full["page"]
    paper = {"GNN_fine": ("8.93", "0.205"), "GNN_coarse": ("12.23", "0.220"),
             "OBB_fine": ("4.78", "0.112")}
    for model, (p_angle, p_dist) in paper.items():
        mean = rep.table[(model, "mean")]
        rows = row_starting(page, model)
        assert rows, f"no comparison row for {model}"
        row = rows[0]
        assert row[1] == f(mean["angle_edge"], 2)
        assert row[2] == p_angle and row[5] == p_dist
        assert float(row[3]) == pytest.approx(mean["angle_edge"] - float(p_angle), abs=5e-3)
        assert row[4] == f(mean["dist_edge"], 3)
        assert row[7] == f(mean["angle_joint"], 2)
    # per-model tables: every category's numbers, as written in table1.csv
    for model in rep.models:
        for cat in [*rep.categories, "mean"]:
            vals = rep.table[(model, cat)]
            hits = [r for r in row_starting(page, cat)
                    if f(vals["angle_edge"], 2) in r and f(vals["dist_edge"], 3) in r
                    and f(vals["edge_acc"], 3) in r]
            assert hits, f"{model}/{cat} numbers missing from the HTML"
    # the Markdown says the same
    fine = rep.table[("GNN_fine", "mean")]
    assert f"| GNN_fine | {f(fine['angle_edge'], 2)} | 8.93 |" in full["md"]
    for ref in ("8.93", "0.205", "12.23", "0.220", "4.78", "0.112"):
        assert ref in full["md"]


def test_table2_next_to_paper(full):
    """Per-category evaluations (one folder each) merged, means next to the paper's Table 2."""
    page = full["page"]
    paper = {"supervised": ("23.66", "3.25"), "semi": ("24.76", "3.39"),
             "semi-weakly": ("17.43", "2.62")}
    for setting, (p_rot, p_ang) in paper.items():
        cats = [c for c in TABLE2 if setting in TABLE2[c][1]]
        # the report reads table2.csv (6 significant digits) and averages the categories
        rot = sum(float(f"{table2_means(c, setting)[0]:.6g}") for c in cats) / len(cats)
        ang = sum(float(f"{table2_means(c, setting)[1]:.6g}") for c in cats) / len(cats)
        cmp = [r for r in row_starting(page, setting) if len(r) == 8]
        assert len(cmp) == 1, setting
        row = cmp[0]
        assert row[1] == str(len(cats))
        assert row[2] == f"{rot:.2f}" and row[3] == p_rot
        assert float(row[4]) == pytest.approx(rot - float(p_rot), abs=6e-3)
        assert row[5] == f"{ang:.2f}" and row[6] == p_ang
        assert float(row[7]) == pytest.approx(ang - float(p_ang), abs=6e-3)
        # per-category rows: category, setting, frames, rotation ...
        for c in cats:
            r_mean, a_mean = table2_means(c, setting)
            assert [c, setting, "2", f(r_mean, 2)] in [r[:4] for r in row_starting(page, c)]
            assert any(r[1] == setting and f(a_mean, 2) in r[4:] for r in row_starting(page, c))
    # the permutation-matched columns of table2.csv stay out of the comparison with the paper
    assert "matched" not in full["md"]
    # frames.csv (per frame) is not a Table 2
    assert "frames.csv" not in page.tables[0][2][2]
    assert "ancsh/eval-laptop/table2.md" in full["html"]  # per-part details referenced
    for ref in ("23.66", "24.76", "17.43", "3.25", "3.39", "2.62"):
        assert ref in full["md"]


def test_every_image_is_an_inline_png(full):
    page = full["page"]
    out = full["out"]
    on_disk = sorted((out / "img").rglob("*.png"))
    # charts: Table 1 errors + accuracy, Table 2, 4 training runs, pseudo-labels; 7 renders
    assert len(page.images) == 2 + 1 + full["info"]["n_curves"] + 1 + full["info"]["n_gallery"]
    assert len(on_disk) == len(page.images)
    for img in page.images:
        src = img["src"]
        assert src.startswith("data:image/png;base64,"), src[:60]
        data = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert data.startswith(PNG_MAGIC) and data[12:16] == b"IHDR"
        w, h = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
        assert (str(w), str(h)) == (img["width"], img["height"]) and w > 50 and h > 50
        assert img["alt"]
    assert page.external == [], "the page must not load anything from outside"
    # gallery renders are the run's own files, byte for byte
    src = (full["root"] / "eval" / "renders" / "GNN_fine" / "7119.png").read_bytes()
    assert base64.b64encode(src).decode() in full["html"]


def test_markdown_references_existing_files(full):
    md, out = full["md"], full["out"]
    refs = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md) + re.findall(r'<img src="([^"]+)"', md)
    assert len(refs) == len(full["page"].images)
    for r in refs:
        p = out / r
        assert p.is_file(), r
        assert p.read_bytes().startswith(PNG_MAGIC)
    assert "## Table 2: partial scans" in md and "ancsh/eval-laptop/table2.csv" in md


def test_training_pseudo_predictions_and_gallery(full):
    page = full["page"]
    # training summary: one row per metrics.csv with its config and epochs
    rows = {r[0]: r for r in page.tables[next(i for i, t in enumerate(page.tables)
                                              if t[0][0] == "metrics.csv")]}
    assert rows["gnn_fine/metrics.csv"][1].startswith("types=fine")
    assert rows["gnn_coarse/metrics.csv"][2] == "6" and rows["axis/metrics.csv"][2] == "4"
    assert "val_select_acc" in rows["axis/metrics.csv"][3]
    # ANCSH trains in two stages whose epochs restart: 7 epochs in sequence
    assert rows["ancsh/semi/metrics.csv"][1:3] == ["category=Laptop, setting=semi, preset=quick, "
                                                   "seed=0", "7"]
    # pseudo-label summary (3 of 6 kept)
    assert ["Table", "3", "2", "1", "0", "0", "0", "66.7"] in row_starting(page, "Table")
    assert ["all", "6", "3", "1", "1", "0", "1", "50.0"] in row_starting(page, "all")
    # predictions: 2 ok, 1 failed, reason shown
    assert ["predict/predictions.csv", "3", "2", "1", "1.50"] in row_starting(
        page, "predict/predictions.csv")
    assert "19179/result.json: missing" in full["html"]
    # gallery: renders grouped by folder, prediction.png under the predict folder
    for group in ("eval/renders/GNN_fine", "eval/renders/OBB_fine", "predict"):
        assert f"<h4>{group}</h4>" in full["html"]
    assert "found: table1 1, table2 2, curves 4, pseudo 1, predictions 1, gallery 7" in \
        " ".join(full["output"].split())


def test_rerun_skips_reports_and_removes_stale_images(tmp_path):
    """A second report elsewhere: the first one (RUN/report) is not collected, images of an
    earlier report go (nothing else), --max-images spreads the gallery over the folders."""
    run = tmp_path / "run"
    for model in ("GNN_fine", "OBB_fine"):
        for sid in ("1", "2", "3"):
            write_png(run / "eval" / "renders" / model / f"{sid}.png")
    write_png(run / "a_plots" / "other.png")  # not a render: shown after the renders
    write_png(run / "data" / "7119" / "parts_render" / "0.png")  # dataset thumbnails: skipped
    assert invoke(run).exit_code == 0
    assert len(list((run / "report" / "img").rglob("*.png"))) == 7
    other = tmp_path / "elsewhere"
    write_png(other / "img" / "mine.png")  # a user's file in the output folder: kept
    res = invoke(run, "--out", other, "--max-images", "5")
    assert res.exit_code == 0, res.output
    assert len(list((other / "img" / "gallery").glob("*.png"))) == 5
    res = invoke(run, "--out", other, "--max-images", "2")
    assert res.exit_code == 0, res.output
    assert (other / "img" / "mine.png").is_file()
    assert len(list((other / "img" / "gallery").glob("*.png"))) == 2  # 3 stale ones removed
    html = (other / "index.html").read_text(encoding="utf-8")
    assert len(parse(html).images) == 2
    assert "2 of the 7 PNGs found are shown" in html  # RUN/report/img is not searched
    groups = re.findall(r"<h4>(eval/renders/[^<]+)</h4>", html)
    assert groups == ["eval/renders/GNN_fine", "eval/renders/OBB_fine"]
    # re-running into the same folder does not collect its own images either
    res = invoke(run)
    assert res.exit_code == 0 and "gallery 7" in " ".join(res.output.split())


def test_partial_run(tmp_path):
    """Only one training run: the rest is reported missing, nothing crashes."""
    run = tmp_path / "gnn"
    write_gnn_metrics(run, "fine", epochs=3)
    res = invoke(run)
    assert res.exit_code == 0, res.output
    html = (run / "report" / "index.html").read_text(encoding="utf-8")
    page = parse(html)
    assert "No Table 1 evaluation (pre-segmented shapes) in this run" in html
    assert "No Table 2 evaluation (partial scans) in this run" in html
    assert "No pseudo-label summary (summary.csv) in this run" in html
    assert "No shape renders (PNG) in this run" in html
    assert len(page.images) == 1 and page.images[0]["src"].startswith("data:image/png;base64,")
    assert 'class=missing>Table 2: partial scans</a>' in html
    assert "missing: table1, table2, pseudo, predictions, gallery" in " ".join(res.output.split())
    md = (run / "report" / "report.md").read_text(encoding="utf-8")
    assert "**Missing:** No Table 2 evaluation (partial scans) in this run" in md
    # the paper's references are quoted even without an evaluation
    assert "8.93" in html and "23.66" in html


def test_empty_and_damaged_runs(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    res = invoke(empty)
    assert res.exit_code == 0, res.output
    page = parse((empty / "report" / "index.html").read_text(encoding="utf-8"))
    assert page.images == []
    assert [r[1] for r in page.tables[0][1:]] == ["missing"] * 6

    bad = tmp_path / "bad"
    (bad / "eval").mkdir(parents=True)
    (bad / "eval" / "table1.csv").write_text("model,category,n_shapes,n_joints,angle_edge\n")
    (bad / "train").mkdir()
    (bad / "train" / "metrics.csv").write_text("epoch,loss,test_acc\n")
    (bad / "renders").mkdir()
    (bad / "renders" / "broken.png").write_bytes(b"not a png at all")
    write_png(bad / "renders" / "r-1" / "a.png", "red")  # file names that slug alike
    write_png(bad / "renders" / "r_1" / "a.png", "blue")
    (bad / "notes.csv").write_bytes(b"\xff\xfe\x00garbage")
    # a Table 1 with NaN cells (a model without joints) still renders
    rep = write_table1(bad / "eval2")
    text = (bad / "eval2" / "table1.csv").read_text().splitlines()
    head = text[0].split(",")
    k = head.index("dist_joint")
    rows = [line.split(",") for line in text[1:]]
    for r in rows:
        r[k] = ""
    (bad / "eval2" / "table1.csv").write_text("\n".join([text[0], *map(",".join, rows)]) + "\n")
    res = invoke(bad)
    assert res.exit_code == 0, res.output
    out = " ".join(res.output.split())
    assert "eval/table1.csv: Table 1 CSV has no rows" in out
    assert "renders/broken.png: not a valid PNG file" in out
    html = (bad / "report" / "index.html").read_text(encoding="utf-8")
    assert "train/metrics.csv: no epoch recorded yet" in html
    page = parse(html)
    mean = rep.table[("GNN_fine", "mean")]
    row = row_starting(page, "GNN_fine")[0]
    assert row[1] == f(mean["angle_edge"], 2) and row[8] == "–"
    assert all(im["src"].startswith("data:image/png;base64,") for im in page.images)
    gallery = sorted((bad / "report" / "img" / "gallery").glob("*.png"))
    assert len(gallery) == 2 and gallery[0].read_bytes() != gallery[1].read_bytes()
    assert not math.isnan(mean["angle_edge"])


def test_missing_run_is_an_error(tmp_path):
    res = invoke(tmp_path / "nope")
    out = " ".join(res.output.split())
    assert res.exit_code == 1
    assert f"{tmp_path / 'nope'}: run folder does not exist" in out.replace("/ ", "/")
    file = tmp_path / "file.txt"
    file.write_text("x")
    res = invoke(file)
    assert res.exit_code == 1 and "not a folder" in " ".join(res.output.split())
    res = invoke(tmp_path, "--out", tmp_path)
    assert res.exit_code == 1 and "cannot be the run folder" in " ".join(res.output.split())
    assert not (tmp_path / "nope").exists()


# --- A real browser ----------------------------------------------------------------------

def test_browser_loads_every_image(full, chromium, tmp_path):
    index = full["out"] / "index.html"
    # mailed alone: copy the single file where no img/ folder exists
    alone = tmp_path / "mailed" / "index.html"
    alone.parent.mkdir()
    shutil.copy(index, alone)
    res = headless(chromium, tmp_path, "--dump-dom", alone.as_uri())
    assert res.returncode == 0, res.stderr[-2000:]
    ok, total = images_loaded(res.stdout)
    assert total == len(full["page"].images) > 0
    assert ok == total, f"only {ok} of {total} images decoded in Chromium"
    # the check can fail: a page with a broken image reports it
    broken = tmp_path / "broken.html"
    html = full["html"].replace("data:image/png;base64,iVBOR", "data:image/png;base64,AAAAA", 1)
    broken.write_text(html, encoding="utf-8")
    ok, total = images_loaded(headless(chromium, tmp_path, "--dump-dom", broken.as_uri()).stdout)
    assert ok == total - 1
    # a screenshot of the top of the page is a real, non-blank image
    shot = tmp_path / "shot.png"
    res = headless(chromium, tmp_path, "--hide-scrollbars", "--window-size=1200,1600",
                    f"--screenshot={shot}", alone.as_uri())
    assert shot.is_file(), res.stderr[-2000:]
    import matplotlib.image as mpimg

    px = mpimg.imread(shot)
    assert px.shape[:2] == (1600, 1200) and float(px[..., :3].std()) > 0.05
