#!/usr/bin/env bash
# Install cpbc into ./.venv (created if missing). With --test, also the test and docs extras
# (pytest, linters, mkdocs) and Debian's chromium for the browser tests of the viewer
# (installed only when missing; needs root). Then warms the compiled kernels' cache.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
if [[ "${1:-}" == "--test" ]]; then
  .venv/bin/python -m pip install --quiet ".[test,docs]"
  if ! command -v chromium >/dev/null 2>&1; then
    if [[ $(id -u) -eq 0 ]]; then
      apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
    else
      echo "note: chromium is missing and this is not root; the browser tests will be skipped" >&2
    fi
  fi
else
  .venv/bin/python -m pip install --quiet .
fi
# Compile the numba kernels once into numba's on-disk cache, for the installed package (run
# from / so that it is the one imported) and for this source tree (what tests run from here
# import), so that a fresh process compiles nothing.
root=$(pwd)
(cd / && "$root/.venv/bin/python" -m cpbc.kernels --warm --check)
.venv/bin/python -m cpbc.kernels --warm --check
