#!/usr/bin/env bash
# Set up viewcomp on Debian 12: system packages (only those missing), a .venv with
# Python >= 3.11, and `pip install -e ".[test]"`. Safe to run again: it only does what is
# missing. Run as root, or as a user who may use sudo (for apt-get).
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT="$(pwd)"
VENV="$ROOT/.venv"

say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }

as_root() {
  if [ "$(id -u)" -eq 0 ]; then
    "$@"
  elif command -v sudo >/dev/null 2>&1; then
    sudo "$@"
  else
    die "need root for: $* (run this script as root or install sudo)"
  fi
}

is_installed() {
  [ "$(dpkg-query -W -f='${db:Status-Status}' "$1" 2>/dev/null || true)" = "installed" ]
}

# --- Debian packages -----------------------------------------------------------------------
# EGL/GL + Mesa (llvmpipe) for headless rendering, Xvfb for windowed tests, ffmpeg for video,
# mpv for the `export-mpv` user shader's test in a real player.
PACKAGES=(libegl1 libgl1 libgl1-mesa-dri xvfb ffmpeg mpv)

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
    as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
      "${MISSING[@]}"
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
# Reinstall only when pyproject.toml changed since the last successful install (or the
# package or the test tools are not importable).
STAMP="$VENV/.viewcomp-install-stamp"
WANT="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$WANT" ] &&
  "$VENV/bin/python" -c 'import viewcomp, pytest, mypy' 2>/dev/null && [ -x "$VENV/bin/ruff" ]; then
  say "viewcomp already installed (pyproject.toml unchanged)"
else
  say 'installing viewcomp: pip install -e ".[test]"'
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -e ".[test]"
  echo "$WANT" >"$STAMP"
fi
say "done"
