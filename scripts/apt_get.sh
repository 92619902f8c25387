#!/usr/bin/env bash
# apt-get as root (or through sudo) that waits, bounded by APT_LOCK_WAIT seconds (default 300),
# while another process holds apt's or dpkg's lock. scripts/setup.sh sources it; run on its
# own it is `apt_get ARGS...`, e.g. `bash scripts/apt_get.sh install -y ffmpeg`.

if ! declare -F say >/dev/null; then
  say() { printf 'setup: %s\n' "$*"; }
  die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }
fi

as_root() {
  if [ "$(id -u)" -eq 0 ]; then
    "$@"
  elif command -v sudo >/dev/null 2>&1; then
    sudo "$@"
  else
    die "need root for: $* (run this script as root or install sudo)"
  fi
}

# apt-get, waiting (bounded by APT_LOCK_WAIT) while another process holds apt's or dpkg's lock:
# `install` waits by itself with DPkg::Lock::Timeout, `update` does not, so a refusal for a
# held lock is retried every 5 s.
apt_get() {
  local limit="${APT_LOCK_WAIT:-300}" start=$SECONDS said="" log rc
  log="$(mktemp)"
  while true; do
    set +e
    as_root env DEBIAN_FRONTEND=noninteractive apt-get -o "DPkg::Lock::Timeout=$limit" "$@" 2>&1 |
      tee "$log"
    rc=${PIPESTATUS[0]}
    set -e
    if [ "$rc" -eq 0 ]; then
      rm -f "$log"
      return 0
    fi
    if ! grep -q 'Could not get lock' "$log"; then
      rm -f "$log"
      die "apt-get $* failed (exit $rc, see above)"
    fi
    if [ $((SECONDS - start)) -ge "$limit" ]; then
      rm -f "$log"
      die "apt is still locked after ${limit} s by another process (see above); wait for it to finish (or raise APT_LOCK_WAIT) and run this again"
    fi
    if [ -z "$said" ]; then
      say "waiting for the apt lock, held by another process (up to ${limit} s)"
      said=1
    fi
    sleep 5
  done
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
  set -euo pipefail
  apt_get "$@"
fi
