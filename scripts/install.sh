#!/usr/bin/env bash
# Install cpbc into ./.venv (created if missing), editable: the source tree is the installed
# package, so its models, scenarios and viewer page are the tree's own and numba's kernel
# cache (cpbc/kernels/__pycache__) is one, filled once. With --test, also the test and docs
# extras (pytest, linters, mkdocs) and Debian's chromium for the browser tests of the viewer
# (installed only when missing; needs root). Then compiles the kernels into that cache, saying
# each module as it goes. Takes about 2–3 min for the packages and 1.5–5 min for the kernels
# on a 2-core machine (the second depends on its load).
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS=0
say() { echo "[install $(printf '%3d' "$SECONDS") s] $*"; }
say "creating .venv and installing cpbc with its dependencies (about 2–3 min)"
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
if [[ "${1:-}" == "--test" ]]; then
  .venv/bin/python -m pip install --quiet -e ".[test,docs]"
  if ! command -v chromium >/dev/null 2>&1; then
    if [[ $(id -u) -eq 0 ]]; then
      say "installing chromium for the viewer's browser tests"
      apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
    else
      echo "note: chromium is missing and this is not root; the browser tests will be skipped" >&2
    fi
  fi
else
  .venv/bin/python -m pip install --quiet -e .
fi
say "compiling the numba kernels once into their on-disk cache (1.5–5 min)"
.venv/bin/python -m cpbc.kernels --warm --check
say "done"
