"""kinmo.render.scene: PyBullet imported without its banner, so logs stay readable."""

from __future__ import annotations

import subprocess
import sys

BANNER = "pybullet build time"


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_pybullet_is_imported_without_its_banner_and_stderr_still_works():
    plain = _run("import pybullet")
    assert plain.returncode == 0, plain.stderr
    assert BANNER in plain.stderr  # what a plain import writes, once per process
    r = _run("import sys\n"
             "from kinmo.render.scene import pybullet_module\n"
             "p = pybullet_module()\n"
             "assert pybullet_module() is p and sys.modules['pybullet'] is p\n"
             "c = p.connect(p.DIRECT); p.disconnect(c)\n"
             "print('direct', p.DIRECT)\n"
             "print('after', file=sys.stderr)\n")
    assert r.returncode == 0, r.stderr
    assert BANNER not in r.stderr + r.stdout
    assert r.stdout.strip() == "direct 2"
    assert r.stderr.strip().endswith("after")  # descriptor 2 is given back
