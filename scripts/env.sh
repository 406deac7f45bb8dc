#!/usr/bin/env bash
# Create (or reuse) kinmo's virtual environment and build the package into it.
#
# The environment lives outside the checkout, in $KINMO_CACHE (default ~/.cache/kinmo),
# keyed by a hash of the Python dependencies declared in pyproject.toml, so it is reused
# while they are unchanged and rebuilt from nothing when they change or on a fresh machine.
# Rust build artefacts are cached there too (CARGO_TARGET_DIR).
#
# Source it (`. scripts/env.sh`) to get an activated environment with `kinmo` built.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cache="${KINMO_CACHE:-$HOME/.cache/kinmo}"
py="${PYTHON:-python3}"
mkdir -p "$cache"

if ! command -v cargo >/dev/null 2>&1; then
  echo "kinmo: cargo (Rust toolchain) is required: see https://rustup.rs" >&2
  exit 1
fi

key="$("$py" - "$root/pyproject.toml" <<'PY'
import hashlib, json, sys, tomllib
with open(sys.argv[1], "rb") as f:
    d = tomllib.load(f)
p = d["project"]
blob = json.dumps([sys.version_info[:2], p["dependencies"], p.get("optional-dependencies", {})], sort_keys=True)
print(hashlib.sha256(blob.encode()).hexdigest()[:16])
PY
)"
venv="$cache/venv-$key"
if [ ! -f "$venv/.complete" ]; then
  echo "kinmo: creating virtual environment $venv (first run downloads torch, a few GB)" >&2
  rm -rf "$venv"
  "$py" -m venv "$venv"
  "$venv/bin/python" -m pip install -q --upgrade pip
  # Dependencies only (the package itself is built by maturin below).
  "$venv/bin/python" - "$root/pyproject.toml" > "$cache/requirements-$key.txt" <<'PY'
import sys, tomllib
with open(sys.argv[1], "rb") as f:
    p = tomllib.load(f)["project"]
deps = list(p["dependencies"]) + list(p.get("optional-dependencies", {}).get("test", []))
print("\n".join(["maturin>=1.8,<2"] + deps))
PY
  "$venv/bin/python" -m pip install -q -r "$cache/requirements-$key.txt"
  touch "$venv/.complete"
  # keep only the newest three environments
  ls -1dt "$cache"/venv-* 2>/dev/null | tail -n +4 | xargs -r rm -rf
fi

export VIRTUAL_ENV="$venv"
export PATH="$venv/bin:$PATH"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$cache/target}"
(cd "$root" && maturin develop --release -q >/dev/null 2>"$cache/maturin.log") || {
  cat "$cache/maturin.log" >&2; echo "kinmo: building the Rust extension failed" >&2; exit 1; }
