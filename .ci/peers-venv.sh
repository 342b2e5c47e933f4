#!/usr/bin/env bash
# Creates target/peers-venv with the Python peers the tests compare against: PyGTide (ETERNA,
# built from source: needs gfortran) and tidegravity (Longman). Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v gfortran >/dev/null; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq gfortran >/dev/null
fi
venv=target/peers-venv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
if ! "$venv/bin/python" -c 'import pygtide, tidegravity' 2>/dev/null; then
  "$venv/bin/python" -m pip install -q pygtide==0.9.7 tidegravity==0.5.0
fi
"$venv/bin/python" -c 'import pygtide, tidegravity; print("peers-venv: pygtide and tidegravity ready")'
