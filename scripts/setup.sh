#!/usr/bin/env bash
# Sets up a fresh machine: the Python venv from pyproject.toml (bpy, trimesh,
# rtree, numpy, the EfficientNet-Lite0 ImageNet weights, pytest, ruff,
# scikit-image) and the release build of the three programs.
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

echo "== building the Rust workspace (release)"
export PYO3_PYTHON="$VENV/bin/python"
cargo build --release --workspace --quiet
echo "== ready: target/release/{grasp-gen,grasp-train,hannes-run}"
