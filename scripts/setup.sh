#!/usr/bin/env bash
# Set up viewcomp on Debian 12: system packages (only those missing), a .venv with
# Python >= 3.11, and viewcomp installed into it with the versions of constraints.txt (the
# ones the tests passed with). Safe to run again: it only does what is missing. Run as root,
# or as a user who may use sudo (for apt-get).
#
#   bash scripts/setup.sh            development: `pip install -e ".[test]"` (pytest, ruff, mypy)
#   bash scripts/setup.sh --runtime  a kiosk: viewcomp alone, no test tools, no Xvfb
#
# APT_LOCK_WAIT (seconds, default 300) bounds the wait for the apt/dpkg lock that another
# process (unattended-upgrades on a fresh machine, say) may hold.
set -euo pipefail

MODE=dev
for arg in "$@"; do
  case "$arg" in
    --runtime) MODE=runtime ;;
    -h | --help)
      sed -n '2,13p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
      exit 0
      ;;
    *)
      printf 'setup: error: unknown option %s (use --runtime, or nothing)\n' "$arg" >&2
      exit 2
      ;;
  esac
done

cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT="$(pwd)"
VENV="$ROOT/.venv"

say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }
# shellcheck source=scripts/apt_get.sh
. "$ROOT/scripts/apt_get.sh"


is_installed() {
  [ "$(dpkg-query -W -f='${db:Status-Status}' "$1" 2>/dev/null || true)" = "installed" ]
}

# --- Debian packages -----------------------------------------------------------------------
# EGL/GL + Mesa (llvmpipe) for headless rendering, Xvfb for windowed tests, ffmpeg for video,
# mpv for the `export-mpv` user shader's test in a real player.
PACKAGES=(libegl1 libgl1 libgl1-mesa-dri ffmpeg mpv)
[ "$MODE" = dev ] && PACKAGES+=(xvfb)

find_python() {
  local candidate
  for candidate in "${PYTHON:-}" python3 python3.13 python3.12 python3.11; do
    [ -n "$candidate" ] || continue
    if command -v "$candidate" >/dev/null 2>&1 &&
      "$candidate" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
      command -v "$candidate"
      return 0
    fi
  done
  return 1
}

if [ ! -x "$VENV/bin/python" ]; then
  # Debian's python3 cannot create a venv without python3-venv.
  PY="$(find_python || true)"
  if [ -z "$PY" ] || ! "$PY" -c 'import ensurepip, venv' 2>/dev/null; then
    PACKAGES+=(python3 python3-venv)
  fi
fi

if command -v dpkg-query >/dev/null 2>&1; then
  MISSING=()
  for pkg in "${PACKAGES[@]}"; do
    is_installed "$pkg" || MISSING+=("$pkg")
  done
  if [ "${#MISSING[@]}" -gt 0 ]; then
    say "installing Debian packages: ${MISSING[*]}"
    apt_get update -qq
    apt_get install -y -q --no-install-recommends "${MISSING[@]}"
  else
    say "Debian packages present: ${PACKAGES[*]}"
  fi
else
  say "no dpkg-query (not Debian?): skipping system packages; need: ${PACKAGES[*]}"
fi

# --- virtual environment -------------------------------------------------------------------
if [ -x "$VENV/bin/python" ]; then
  say "using existing $VENV ($("$VENV/bin/python" --version 2>&1))"
else
  PY="$(find_python)" || die "no Python >= 3.11 found (Debian 12: apt-get install python3)"
  say "creating $VENV with $PY ($("$PY" --version 2>&1))"
  "$PY" -m venv "$VENV"
fi
"$VENV/bin/python" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' ||
  die "$VENV has Python $("$VENV/bin/python" --version 2>&1); viewcomp needs >= 3.11 (delete .venv and rerun)"

# --- viewcomp itself -----------------------------------------------------------------------
# Reinstall only when pyproject.toml or constraints.txt changed since the last successful
# install of this mode (or the package is not importable).
STAMP="$VENV/.viewcomp-install-stamp"
WANT="$MODE $(cat pyproject.toml constraints.txt | sha256sum | cut -d' ' -f1)"
PIP=("$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -c constraints.txt)
if [ "$MODE" = dev ]; then
  CHECK='import viewcomp, pytest, mypy'
else
  CHECK='import viewcomp'
fi
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$WANT" ] && "$VENV/bin/python" -c "$CHECK" 2>/dev/null; then
  say "viewcomp already installed ($MODE; pyproject.toml and constraints.txt unchanged)"
elif [ "$MODE" = dev ]; then
  say 'installing viewcomp: pip install -e ".[test]" -c constraints.txt'
  "${PIP[@]}" -e ".[test]"
  echo "$WANT" >"$STAMP"
else
  say 'installing viewcomp for running only: pip install . -c constraints.txt (no test tools)'
  "${PIP[@]}" .
  if "$VENV/bin/python" -c 'import pytest' 2>/dev/null; then
    say "note: $VENV also holds test tools from a development set-up; a kiosk needs a fresh clone"
  fi
  echo "$WANT" >"$STAMP"
fi
if [ "$MODE" = dev ]; then
  # the tracker's people test draws a head scanned in 3-D (menpo3d's data, from PyPI)
  "$VENV/bin/python" scripts/fetch_scan.py || die "could not fetch the tests' scanned head (scripts/fetch_scan.py)"
fi
say "done"
