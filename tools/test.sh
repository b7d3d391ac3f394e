#!/usr/bin/env bash
# The whole test suite, in a local virtual environment it creates and fills itself.
source "$(dirname "$0")/env.sh" "test"
cd "$ROOT"
set +e
python -m pytest -q -p no:cacheprovider "${@:-test}"
rc=$?
if [ "$rc" = 5 ]; then
  echo "error: pytest collected no tests" >&2
  exit 1
fi
exit "$rc"
