#!/usr/bin/env bash
# Set up everything kinmo needs (cached venv, Rust extension) and run all tests:
# cargo fmt/clippy/test on the Rust crates, then pytest.
#
#   ./scripts/test.sh            # everything
#   ./scripts/test.sh -k obb     # extra arguments go to pytest
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=env.sh
. "$root/scripts/env.sh"
cd "$root"
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy"
cargo clippy --workspace --all-targets --release -q -- -D warnings
echo "== cargo test"
# Property tests draw from a fixed seed so that a run is reproducible (set PROPTEST_RNG_SEED
# to explore others; cases that once failed are replayed first from
# rust/kinmo-geometry/proptest-regressions/ and tests/*.proptest-regressions).
export PROPTEST_RNG_SEED="${PROPTEST_RNG_SEED:-20261122}"
cargo test -p kinmo-geometry --release -q 2>&1 | grep -v "^$"
# the report tests open the HTML in a headless Chromium: install it on a fresh machine
command -v chromium >/dev/null || { [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null && (apt-get update -qq && apt-get install -y -qq chromium >/dev/null); } || true
echo "== pytest"
python -m pytest -q -p no:cacheprovider "$@"
