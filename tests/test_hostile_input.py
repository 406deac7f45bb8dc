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
