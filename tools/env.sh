# Sourced by tools/*.sh: create .venv in the repository root (once) and install
# the package with the given extras; reinstall only when setup.py changed.  After an
# install, `glpma-fk precompile` compiles the solvers once (a line per solver), so that
# no later command waits for Numba.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
EXTRAS="${1:-}"
PY="${PYTHON:-python3}"
if ! "$VENV/bin/python" -c "" 2>/dev/null; then
  if ! "$PY" -m venv "$VENV" 2>/dev/null; then
    # Debian/Ubuntu ship venv separately
    if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
      apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null
      rm -rf "$VENV"; "$PY" -m venv "$VENV"
    else
      echo "error: '$PY -m venv' failed; install python3-venv (sudo apt-get install python3-venv)" >&2
      exit 1
    fi
  fi
fi
STAMP="$VENV/.installed-$(cat "$ROOT/setup.py" | sha1sum | cut -c1-12)-${EXTRAS//,/_}"
if [ ! -f "$STAMP" ]; then
  (
    # two commands started together install one after the other
    exec 9>"$VENV/.install.lock"
    flock 9
    if [ ! -f "$STAMP" ]; then
      "$VENV/bin/python" -m pip install -q --upgrade pip >/dev/null
      "$VENV/bin/python" -m pip install -q -e "$ROOT${EXTRAS:+[$EXTRAS]}"
      "$VENV/bin/glpma-fk" precompile
      touch "$STAMP"
    fi
  )
fi
export PATH="$VENV/bin:$PATH"
export CYCLONEDDS_URI="${CYCLONEDDS_URI:-file://$ROOT/config/cyclonedds-localhost.xml}"
