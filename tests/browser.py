"""A real browser for the tests: headless Chromium, found on PATH or installed with apt-get.

The report's page counts its decoded images into ``data-images-loaded`` / ``data-images-total``
on ``<body>`` (:mod:`kinmo.report.build`); :func:`images_loaded` reads them from a DOM dump.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

_BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def _find_browser() -> str | None:
    for name in _BROWSERS:
        exe = shutil.which(name)
        if exe:
            return exe
    return None


def find_chromium() -> str:
    """A headless-capable Chromium: found on PATH, or installed with apt-get when root."""
    exe = _find_browser()
    if exe is None and hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get"):
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        subprocess.run(["apt-get", "update", "-qq"], env=env, capture_output=True, timeout=900)
        subprocess.run(["apt-get", "install", "-y", "-qq", "chromium"], env=env,
                       capture_output=True, timeout=1800)
        exe = _find_browser()
    if exe is None:
        pytest.fail("no Chromium found (looked for " + ", ".join(_BROWSERS) + "); install it, "
                    "e.g. `apt-get install -y chromium` (Debian) as root")
    return exe


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
