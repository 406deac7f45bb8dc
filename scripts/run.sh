#!/usr/bin/env bash
# Set up everything kinmo needs (cached venv, Rust extension) and run a kinmo command:
#
#   ./scripts/run.sh demo                 # the whole pipeline on generated objects
#   ./scripts/run.sh prepare ../shared/data/partnet-mobility
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=env.sh
. "$root/scripts/env.sh"
exec kinmo "$@"
