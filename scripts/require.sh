# What a test run requires, checked before anything is built; sourced by scripts/test.sh and
# .ci/run. Under KINMO_REQUIRE_DATA=1 (CI) a missing shared dataset, and under it or
# KINMO_REQUIRE_BROWSER=1 a missing Chromium, stop the run at once with one line.
# tests/conftest.py checks the same when pytest starts without this script.

# kinmo_flag NAME: whether the variable NAME is set to something other than empty or 0.
kinmo_flag() { case "${!1:-}" in "" | 0) return 1 ;; *) return 0 ;; esac; }

# kinmo_require_data ROOT: the shared real objects of checkout ROOT ($KINMO_DATA, else
# ../shared/data beside it) hold partnet-mobility/ and partnet/, when KINMO_REQUIRE_DATA asks.
kinmo_require_data() {
  kinmo_flag KINMO_REQUIRE_DATA || return 0
  local data="${KINMO_DATA:-$(dirname "$1")/shared/data}" why=""
  if [ ! -d "$data/partnet-mobility" ] && [ ! -d "$data/partnet" ]; then
    why="no shared dataset at $data"
  elif [ ! -d "$data/partnet-mobility" ]; then
    why="$data has no partnet-mobility/"
  elif [ ! -d "$data/partnet" ]; then
    why="$data has no partnet/"
  fi
  [ -z "$why" ] && return 0
  echo "kinmo: KINMO_REQUIRE_DATA=$KINMO_REQUIRE_DATA but $why: set KINMO_DATA=/path/to/data holding partnet-mobility/ and partnet/" >&2
  exit 1
}

# The browsers the report and viewer tests can drive, in the order tests/browser.py looks.
KINMO_BROWSERS="chromium chromium-browser google-chrome google-chrome-stable"

# kinmo_browser: whether one of them is on PATH.
kinmo_browser() {
  local b
  for b in $KINMO_BROWSERS; do command -v "$b" >/dev/null && return 0; done
  return 1
}

# kinmo_require_browser: a Chromium is on PATH, when KINMO_REQUIRE_BROWSER or KINMO_REQUIRE_DATA asks.
kinmo_require_browser() {
  local flag
  for flag in KINMO_REQUIRE_BROWSER KINMO_REQUIRE_DATA; do
    kinmo_flag "$flag" || continue
    kinmo_browser && return 0
    echo "kinmo: $flag=${!flag} but no Chromium on PATH (looked for ${KINMO_BROWSERS// /, }): install one, see the README's tests" >&2
    exit 1
  done
}
