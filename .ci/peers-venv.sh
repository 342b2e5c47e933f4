#!/usr/bin/env bash
# Creates target/peers-venv with the Python peers the tests compare against: PyGTide (ETERNA,
# built from source: needs gfortran), tidegravity (Longman), allantools (Allan deviation),
# DuckDB (reads apply's Parquet output), scipy (the triad's second opinion and the gravity
# filter's; allantools brings it, and it is checked here by name), boule (GRS80 normal
# gravity) and shipgrav (the Eotvos term).
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
# A venv whose pip bootstrap failed (a clean CI machine once refused `ensurepip` with no reason
# given) is made again without pip, its bootstrap's own words printed, then pip put in by the
# interpreter's own pip.
make_venv() {
  local log
  log=$(mktemp)
  if python3 -m venv "$venv" >"$log" 2>&1; then rm -f "$log"; return; fi
  echo "peers-venv: python3 -m venv failed:"; cat "$log"; rm -f "$log"
  rm -rf "$venv"
  python3 -m venv --without-pip "$venv"
  if ! "$venv/bin/python" -m ensurepip --default-pip; then
    echo "peers-venv: ensurepip failed again; installing pip with $(python3 -m pip --version)"
    python3 -m pip --python "$venv/bin/python" install -q pip
  fi
}
[ -x "$venv/bin/python" ] && "$venv/bin/python" -m pip --version >/dev/null 2>&1 || { rm -rf "$venv"; make_venv; }
if ! "$venv/bin/python" -c 'import pygtide, tidegravity, allantools' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q numpy==1.25.0 pygtide==0.9.7 tidegravity==0.5.0 allantools==2024.6
fi
if ! "$venv/bin/python" -c 'import duckdb' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q duckdb==1.5.6
fi
if ! "$venv/bin/python" -c 'import scipy.optimize' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q scipy
fi
if ! "$venv/bin/python" -c 'import boule, shipgrav' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q numpy==1.25.0 boule==0.6.0 shipgrav==1.0.11
fi
"$venv/bin/python" -c 'import pygtide, tidegravity, allantools, duckdb, scipy, boule, shipgrav; print("peers-venv: pygtide, tidegravity, allantools, scipy", scipy.__version__, "duckdb", duckdb.__version__, "boule", boule.__version__, "and shipgrav ready")'
