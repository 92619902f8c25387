#!/usr/bin/env bash
# Set up (scripts/setup.sh), then the import-cycle check, the size check, the type check
# (mypy), lint, format check and tests.
# Arguments go to pytest.
# Runs every check even after a failure, and exits non-zero if any failed.
# Under CI=true, VIEWCOMP_REQUIRE_GL=1: GL tests fail instead of skipping when GL is missing.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash scripts/setup.sh

if [ "${CI:-}" = "true" ]; then
  export VIEWCOMP_REQUIRE_GL=1
  echo "test: CI=true, so VIEWCOMP_REQUIRE_GL=1 (missing GL is a failure, not a skip)"
fi

FAILED=()
run() {
  echo "test: $*"
  if ! "$@"; then
    FAILED+=("$*")
  fi
}

run .venv/bin/python scripts/check_imports.py
run .venv/bin/python scripts/check_sizes.py
run .venv/bin/python scripts/check_types.py
run .venv/bin/ruff check .
run .venv/bin/ruff format --check .
run .venv/bin/python -m pytest "$@"

if [ "${#FAILED[@]}" -gt 0 ]; then
  printf 'test: FAILED: %s\n' "${FAILED[@]}" >&2
  exit 1
fi
echo "test: all checks passed"
