"""A real browser for the tests: headless Chromium, found on PATH (the ``chromium`` fixture).

The report's page counts its decoded images into ``data-images-loaded`` / ``data-images-total``
on ``<body>`` (:mod:`kinmo.report.build`); :func:`images_loaded` reads them from a DOM dump.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

#: The executables looked for on PATH, in this order (the same as ``scripts/require.sh``).
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_browser() -> str | None:
    """A headless-capable Chromium on PATH, or None (nothing is installed here: see the
    README's tests; the ``chromium`` fixture skips or fails)."""
    for name in BROWSERS:
        exe = shutil.which(name)
        if exe:
            return exe
    return None


def headless(exe: str, tmp: Path, *args: str) -> subprocess.CompletedProcess:
    """Run Chromium headless with a fresh profile under ``tmp``."""
    return subprocess.run(
        [exe, "--headless", "--disable-gpu", "--no-sandbox", "--no-first-run",
         f"--user-data-dir={tmp / 'profile'}", *args],
        capture_output=True, text=True, timeout=180)


def images_loaded(dom: str) -> tuple[int, int]:
    """(decoded, total) images of a report page, from Chromium's ``--dump-dom`` output."""
    m = re.search(r"<body[^>]*>", dom)
    assert m, f"no <body> in the DOM dump: {dom[:300]!r}"
    tot = re.search(r'data-images-total="(\d+)"', m.group(0))
    ok = re.search(r'data-images-loaded="(\d+)"', m.group(0))
    assert tot and ok, f"the page's load script did not run: {m.group(0)}"
    return int(ok.group(1)), int(tot.group(1))
