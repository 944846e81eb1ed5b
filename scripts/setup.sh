#!/usr/bin/env bash
# Sets up a fresh machine: the Python venv from pyproject.toml (bpy, trimesh,
# rtree, numpy, the EfficientNet-Lite0 ImageNet weights, pytest, ruff,
# scikit-image), Debian's chromium where missing (the report pages' test)
# and the release build of the three programs.
# Idempotent: re-running only redoes what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null || PYTHON=python3
"$PYTHON" -c 'import sys; assert sys.version_info[:2] == (3, 11), "Python 3.11 is required (bpy 5.0 wheels)"'

VENV=${GRASP_VENV:-$ROOT/.venv}
STAMP="$VENV/.installed-$(sha256sum pyproject.toml | cut -c1-16)"
if [ ! -f "$STAMP" ]; then
  echo "== creating the Python environment in $VENV"
  "$PYTHON" -m venv "$VENV"
  "$VENV/bin/pip" install --quiet --upgrade pip
  "$VENV/bin/pip" install --quiet -e ".[dev]"
  touch "$STAMP"
fi

# The report pages' browser test (docs/testing.md) opens them in headless
# Chromium: Debian's package, installed where missing.
if ! command -v chromium >/dev/null; then
  SUDO=''
  [ "$(id -u)" -eq 0 ] || SUDO=sudo
  if command -v apt-get >/dev/null && { [ -z "$SUDO" ] || command -v sudo >/dev/null; }; then
    echo "== installing chromium (headless browser for the report pages' test)"
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null
  else
    echo "note: no chromium and no apt-get to install it: the report pages' browser test will fail under GRASP_REQUIRE_BROWSER=1" >&2
  fi
fi

echo "== building the Rust workspace (release)"
export PYO3_PYTHON="$VENV/bin/python"
cargo build --release --workspace --quiet
echo "== ready: target/release/{grasp-gen,grasp-train,hannes-run}"
