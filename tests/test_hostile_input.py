"""Hostile inputs (issue 21, findings 4-12): each finding reproduced as a test.

Findings 1-2 (names as paths, outputs over inputs) are in ``tests/data/test_names.py`` and
``tests/test_io.py``; finding 3 (stale caches) with the cache readers.
"""

from __future__ import annotations

import json

import pytest
from conftest import write_cabinet
from typer.testing import CliRunner

from kinmo.cli import app

runner = CliRunner()


# ---- finding 6: printed names are literal text ------------------------------------------------

def test_literal_keeps_markup_brackets_and_emoji_codes():
    from kinmo.progress import console, literal

    c = console(record=True, width=200)
    for name in ("brk[old]/", "[/]", "a[red]b[/]", ":x:", "a\x01b"):
        c.print(f"[red]name[/] {literal(name)}")
    text = c.export_text()
    assert "brk[old]/" in text and "[/]" in text and "a[red]b[/]" in text
    assert ":x:" in text and "\u274c" not in text
    assert "a\\x01b" in text and "\x01" not in text


def test_prepare_prints_folder_names_with_markup_literally(tmp_path):
    data = tmp_path / "brk[" / "]:x:"
    write_cabinet(data / "a[red]")
    out = tmp_path / "out[" / "]"
    res = runner.invoke(app, ["prepare", str(data), "-o", str(out)])
    assert res.exit_code == 0, res.output
    flat = "".join(res.output.split())
    assert f"->{out}/manifest.csv".replace(" ", "") in flat
    assert "\u274c" not in res.output
    assert (out / "a[red].npz").is_file()


# ---- finding 8: option values checked up front; diverged training saves nothing ---------------

@pytest.mark.parametrize("args,needle", [
    (["--device", "foo"], "--device foo"),
    (["--device", "cuda:99"], "--device cuda:99"),
    (["--hinge-max", "nan"], "--hinge-max nan"),
    (["--ranker", "/etc/passwd"], "not a ranker file"),
])
def test_predict_refuses_bad_option_values_in_one_line(tiny_gnn, tmp_path, args, needle):
    res = runner.invoke(app, ["predict", str(tiny_gnn["data"]), "-m", str(tiny_gnn["run"]),
                              "-o", str(tmp_path / "out"), "-q", *args])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], res.output
    assert "Traceback" not in res.output and not (tmp_path / "out").exists()


@pytest.mark.parametrize("lr", ["nan", "inf", "1e30", "0", "-1"])
def test_train_gnn_refuses_bad_learning_rates(tiny_gnn, tmp_path, lr):
    res = runner.invoke(app, ["train", "gnn", "-d", str(tiny_gnn["cache"]), "-o", str(tmp_path / "r"),
                              "-q", "--lr", lr])
    assert res.exit_code == 2, res.output
    assert res.output.startswith("error: --lr") and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()


def test_diverged_training_stops_and_saves_no_model(tiny_gnn, tmp_path):
    from kinmo.errors import KinmoTrainingError
    from kinmo.train.config import preset
    from kinmo.train.gnn import train_gnn
    from kinmo.train.split import Split

    cfg = preset("tiny", n_points=32, threads=1, epochs=3, batch_size=2, lr=1e30)
    with pytest.raises(KinmoTrainingError, match="diverged"):
        train_gnn(tiny_gnn["cache"], tmp_path / "run", cfg, split=Split(["c1", "c2"], []),
                  progress=False)
    assert not list(tmp_path.rglob("*.pt"))
