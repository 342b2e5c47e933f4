#!/usr/bin/env bash
# Creates target/peers-venv with the Python peers the tests compare against: PyGTide (ETERNA,
# built from source: needs gfortran), tidegravity (Longman), allantools (Allan deviation),
# DuckDB (reads apply's Parquet output) and scipy (the triad's second opinion; allantools
# brings it, and it is checked here by name).
# numpy is pinned with them: PyGTide's compiled part breaks under a numpy other than the one
# it was built with, and tidegravity asks for 1.25. Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v gfortran >/dev/null; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq gfortran >/dev/null
fi
venv=target/peers-venv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
if ! "$venv/bin/python" -c 'import pygtide, tidegravity, allantools' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q numpy==1.25.0 pygtide==0.9.7 tidegravity==0.5.0 allantools==2024.6
fi
if ! "$venv/bin/python" -c 'import duckdb' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q duckdb==1.5.6
fi
if ! "$venv/bin/python" -c 'import scipy.optimize' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q scipy
fi
"$venv/bin/python" -c 'import pygtide, tidegravity, allantools, duckdb, scipy; print("peers-venv: pygtide, tidegravity, allantools, scipy", scipy.__version__, "and duckdb", duckdb.__version__, "ready")'
