#!/usr/bin/env bash
# A fast subset of the suite (core, CLI, statuses, DDS round trip) on the oldest versions setup.py
# accepts, in a virtual environment of its own (.venv-floor).  The floors are what Ubuntu 24.04's ROS
# users get, or the oldest release with a wheel for this Python (setup.py says which); .ci/run runs this.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
VENV="$ROOT/.venv-floor"
PY="${PYTHON:-python3}"
# exactly the floors of setup.py's install_requires (a test checks that they agree)
FLOORS=(numpy==1.24.0 numba==0.58.0 PyYAML==6.0 cyclonedds==11.0.1 scipy==1.10.0)
#: the subset: models, estimator, statuses, units, the CLI, the DDS node's round trip
SUBSET=(test/test_models.py test/test_estimator.py test/test_statuses.py test/test_units.py test/test_cli.py
        "test/test_dds_integration.py::test_independent_contract_participant_sees_the_poses")
STAMP="$VENV/.installed-$(printf '%s ' "${FLOORS[@]}" | cat - "$ROOT/setup.py" | sha1sum | cut -c1-12)"
[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
if [ ! -f "$STAMP" ]; then
  "$VENV/bin/python" -m pip install -q --upgrade pip >/dev/null
  # the floors first, then the package and the test tools without letting pip move the floors
  "$VENV/bin/python" -m pip install -q --only-binary=:all: "${FLOORS[@]}"
  "$VENV/bin/python" -m pip install -q "pytest>=7,<9" "hypothesis>=6" "tqdm>=4.60" "${FLOORS[@]}"
  "$VENV/bin/python" -m pip install -q --no-deps -e "$ROOT"
  touch "$STAMP"
fi
# a compiled-code cache of its own: another numba must not overwrite the main environment's cache
export NUMBA_CACHE_DIR="$VENV/numba-cache"
export CYCLONEDDS_URI="${CYCLONEDDS_URI:-file://$ROOT/config/cyclonedds-localhost.xml}"
cd "$ROOT"
"$VENV/bin/python" -c "import numpy, numba, yaml; from importlib.metadata import version; print('floor environment: numpy', numpy.__version__, \
'numba', numba.__version__, 'PyYAML', yaml.__version__, 'cyclonedds', version('cyclonedds'))"
"$VENV/bin/python" -m glpma_ros precompile --solvers glpma g3pcx
exec "$VENV/bin/python" -m pytest -q -p no:cacheprovider "${@:-${SUBSET[@]}}"
