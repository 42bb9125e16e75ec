#!/usr/bin/env bash
# Sets up everything the project needs on a fresh machine, idempotently:
#   1. Debian libraries: libusb-1.0-0 (open3d), libegl1/libgl1 (optional EEVEE/Workbench), libfreeimage3
#      (the tests open frame EXRs with imageio's FreeImage plugin).
#   2. A Python 3.13 virtual environment in .venv with the project installed (editable) and
#      its pinned dependencies. Reinstalls only when pyproject.toml changed.
# Usage: bash tools/bootstrap.sh        (then use .venv/bin/python)
set -euo pipefail
cd "$(dirname "$0")/.."

log() { printf '[bootstrap] %s\n' "$*" >&2; }

# --- Debian packages ---------------------------------------------------------------
debs=(libusb-1.0-0 libegl1 libegl-mesa0 libgl1-mesa-dri libfreeimage3)
missing=()
for pkg in "${debs[@]}"; do
  dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  log "installing Debian packages: ${missing[*]}"
  $sudo apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# --- Python 3.13 -----------------------------------------------------------------
find_python() {
  for cand in python3.13 "$HOME/.pyenv/versions/3.13"*/bin/python3.13 /usr/local/bin/python3.13 /usr/bin/python3.13; do
    if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; assert sys.version_info[:2] == (3, 13)' 2>/dev/null; then
      command -v "$cand"; return 0
    fi
  done
  return 1
}
if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import sys; assert sys.version_info[:2] == (3, 13)' 2>/dev/null; then
  py=$(find_python) || { log "error: Python 3.13 not found (bpy 5.2 needs it); install python3.13 and rerun"; exit 1; }
  log "creating .venv with $py"
  rm -rf .venv
  "$py" -m venv .venv
fi

# --- Python packages -----------------------------------------------------------------
stamp=.venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
  log "installing Python packages (about 1.5 minutes on a fresh machine)"
  pip_log=.venv/pip-install.log
  if ! { .venv/bin/python -m pip install --disable-pip-version-check --upgrade pip &&
         .venv/bin/python -m pip install --disable-pip-version-check -e '.[test]'; } > "$pip_log" 2>&1; then
    tail -n 40 "$pip_log" >&2
    log "error: pip install failed (full log: $pip_log)"
    exit 1
  fi
  rm -f .venv/.installed-*
  touch "$stamp"
fi
log "ready: .venv/bin/python $(.venv/bin/python -c 'import sys; print(sys.version.split()[0])')"
