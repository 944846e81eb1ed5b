#!/usr/bin/env bash
# Sets up (scripts/setup.sh) and runs every test: Rust (unit, integration and
# cross-program tests), Python tests of blender_scripts, and the format/lint
# checks.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
VENV=${GRASP_VENV:-$(pwd)/.venv}
export PYO3_PYTHON="$VENV/bin/python"
# Tests that need Blender fail, rather than skip, without the venv.
export GRASP_REQUIRE_BLENDER=1

echo "== lint"
cargo fmt --all -- --check
cargo clippy --release --workspace --all-targets --quiet -- -D warnings
"$VENV/bin/ruff" check blender_scripts tests
"$VENV/bin/ruff" format --check blender_scripts tests

echo "== python tests"
"$VENV/bin/python" -m pytest -q tests/python

echo "== rust tests"
cargo test --release --workspace
