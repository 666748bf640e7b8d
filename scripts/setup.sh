#!/usr/bin/env bash
# One setup recipe for the README, CI and the Docker image.
# Creates .venv (or uses $VENV), installs the CPU build of torch FIRST (pinned, so pip never
# resolves a multi-GB CUDA build), then this package under constraints: the runtime only by
# default (`make smoke`), with EXTRAS=dev the test, lint and docs tools too (`make test`,
# `make setup`; EXTRAS=dev,track adds the trackers).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${VENV:-.venv}"
PY="${PYTHON:-python3}"
EXTRAS="${EXTRAS:-}"
if [ "${SKIP_VENV:-0}" != "1" ]; then
  [ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
  PIP="$VENV/bin/pip"
else
  PIP="$PY -m pip"
fi
$PIP install --quiet --upgrade pip
# torch first: exactly the CPU build; a looser requirement would pull CUDA wheels.
$PIP install --quiet "torch==2.13.0" ${TORCH_INDEX_URL:+--index-url "$TORCH_INDEX_URL"}
$PIP install --quiet -c constraints.txt -e ".${EXTRAS:+[$EXTRAS]}"
