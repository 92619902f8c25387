#!/usr/bin/env bash
# Write constraints.txt anew from .venv: run it after upgrading a package in .venv and passing
# `bash scripts/test.sh` with it, so that every set-up installs what the tests passed with.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
tmp="$(mktemp constraints.txt.XXXXXX)"
trap 'rm -f "$tmp"' EXIT
{
  sed -n '/^#/p' constraints.txt
  .venv/bin/python -m pip freeze --exclude-editable --disable-pip-version-check |
    grep -iv '^viewcomp[=@ ]' | LC_ALL=C sort -f
} >"$tmp"
mv "$tmp" constraints.txt
trap - EXIT
echo "wrote constraints.txt ($(grep -vc '^#' constraints.txt) packages)"
