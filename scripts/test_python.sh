#!/usr/bin/env bash
# Tests of the Python bindings (crates/python) and of the MuJoCo equivalent model (crossval/):
# creates/updates .venv (scripts/venv), builds and installs the bindings (maturin, release), runs
# crates/python/tests/test_bindings.py. Exit status non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/venv
VIRTUAL_ENV="$PWD/.venv" .venv/bin/maturin develop --release --quiet -m crates/python/Cargo.toml
exec .venv/bin/python crates/python/tests/test_bindings.py
