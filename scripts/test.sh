#!/usr/bin/env bash
# Sets up (scripts/setup.sh) and runs every test: Rust (unit, integration and
# cross-program tests), Python tests of blender_scripts, the format/lint
# checks, and the cluster recipe on a real single-node Slurm
# (scripts/slurm-test.sh: needs root, installs slurm-wlm and munge).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
VENV=${GRASP_VENV:-$(pwd)/.venv}
export PYO3_PYTHON="$VENV/bin/python"
# Tests that need the venv (bpy, the pip-installed ImageNet weights),
# ../shared/ycb or Chromium (the report pages) fail, instead of skipping,
# when it is missing (docs/testing.md).
export GRASP_REQUIRE_BLENDER=1
export GRASP_REQUIRE_SHARED=1
export GRASP_REQUIRE_BROWSER=1

echo "== lint"
cargo fmt --all -- --check
cargo clippy --release --workspace --all-targets --quiet -- -D warnings
# The lab's benchmarks (grasp-train bench-heads/bench-backbone, grasp-gen
# bench-plan and objects bench-queries) are built only with the `lab`
# feature: lint them too.
cargo clippy --release --workspace --all-targets --features lab --quiet -- -D warnings
"$VENV/bin/ruff" check blender_scripts tests
"$VENV/bin/ruff" format --check blender_scripts tests

echo "== python tests"
"$VENV/bin/python" -m pytest -q tests/python

echo "== rust tests"
cargo test --release --workspace

echo "== cluster recipe on Slurm (docs/cluster.md)"
scripts/slurm-test.sh
