"""Progress bars captured in a log (no terminal, as on a cluster) stay readable."""

from __future__ import annotations

import os
import subprocess
import sys

SCRIPT = """
from kinmo.progress import TrainingBar
with TrainingBar(True, "train gnn") as bar:
    t = bar.task("epochs", 3)
    bar.advance(t, 3, info="loss 0.133 acc 0.955 | test acc 0.979 moving recall 0.913 angle 9.1 deg pos 0.042")
    bar.log("axis net epoch 3: loss 0.544 acc 0.689")
"""


def test_a_bar_written_to_a_log_is_not_cut_to_80_columns():
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "FORCE_COLOR", "TERM")}
    r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "angle 9.1 deg pos 0.042" in r.stderr and "…" not in r.stderr
    assert r.stderr.count("train gnn") == 1  # the bar is printed once, not repeated


def test_help_written_to_a_log_is_not_cut_to_80_columns():
    env = {k: v for k, v in os.environ.items()
           if k not in ("COLUMNS", "FORCE_COLOR", "TERM", "TERMINAL_WIDTH")}
    r = subprocess.run([sys.executable, "-m", "kinmo", "eval", "user-format", "--help"],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "[default: generic,semantic,leaf,partnet]" in r.stdout and "…" not in r.stdout


TABLE = """
from rich.table import Table
from kinmo.progress import console
t = Table(title="Pseudo-labels")
for c in ("category", "shapes", "kept", "rejected low score", "rejected no motion", "failed"):
    t.add_column(c)
t.add_row("StorageFurniture", "13", "7", "1", "5", "0")
t.add_row("all", "141", "114", "4", "23", "0")
console().print(t)
"""


def test_a_report_table_written_to_a_log_is_not_cut_to_80_columns():
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "FORCE_COLOR", "TERM")}
    r = subprocess.run([sys.executable, "-c", TABLE], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "StorageFurniture" in r.stdout and "rejected no motion" in r.stdout
    assert "…" not in r.stdout


WIDE = """
from rich.table import Table
from kinmo.progress import console, print_table
t = Table(title="Table 2 - Microwave")
for c in ("setting", "frames", "train scans", "rot.", "transl.", "IoU", "state", "axis", "axis dist."):
    t.add_column(c, justify="right")
for s in ("supervised", "semi", "semi-weakly"):
    t.add_row(s, "24", "48+0+0", *["25.31 (32.20 / 31.84 / 32.21 / 4.99)"] * 6)
print_table(console(), t)
"""


def test_a_table_wider_than_the_log_keeps_one_line_per_row():
    # Table 2 of a category with three joints needs more than the log's 200 columns; the
    # plain console wraps its cells over two lines, print_table widens it for the table
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "FORCE_COLOR", "TERM")}
    r = subprocess.run([sys.executable, "-c", WIDE], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    rows = [ln for ln in r.stdout.splitlines() if "(32.20 / 31.84 / 32.21 / 4.99)" in ln]
    assert len(rows) == 3 and all(ln.count("25.31 (") == 6 for ln in rows), r.stdout
    assert max(map(len, r.stdout.splitlines())) > 200
    plain = subprocess.run([sys.executable, "-c", WIDE.replace("print_table(console(), t)", "console().print(t)")],
                           capture_output=True, text=True, env=env, timeout=120)
    assert "25.31 (" in plain.stdout  # rich alone wraps every such cell over two lines
    assert not any("(32.20 / 31.84 / 32.21 / 4.99)" in ln for ln in plain.stdout.splitlines())


REPEATS = """
import logging
from kinmo.progress import setup_logging
setup_logging(0, {})
log = logging.getLogger("kinmo.ranges.predict")
for _ in range(3):
    log.warning("%s: part %r is blocked both ways", "45332", "drawer")
log.warning("%s: part %r is blocked both ways", "45332", "door")
for _ in range(2):
    log.error("45332: failed")
"""


def test_a_log_prints_a_repeated_warning_once_and_every_error():
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "FORCE_COLOR", "TERM", "KINMO_LOG")}
    r = subprocess.run([sys.executable, "-c", REPEATS], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("part 'drawer' is blocked") == 1
    assert r.stderr.count("part 'door' is blocked") == 1
    assert r.stderr.count("45332: failed") == 2
