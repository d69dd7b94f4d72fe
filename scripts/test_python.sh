#!/usr/bin/env bash
# Tests of the Python bindings (crates/python) and of the MuJoCo equivalent model (crossval/):
# creates/updates .venv (scripts/venv), builds and installs the bindings (maturin, release unless PNEUFLEX_PY_DEV), runs
# crates/python/tests/test_bindings.py, then the MuJoCo plugin's tests (crates/python/tests/test_mujoco_plugin.py;
# the plugin built in release unless PNEUFLEX_MUJOCO_PLUGIN names a build). Exit status non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/venv
# PNEUFLEX_PY_DEV=1 (scripts/test sets it): a dev build, which reuses the workspace build's dependencies
# (10 s against 7-8 min for a release build of the whole tree in CI; the tests run 5 s slower).
profile=(--release); [ -n "${PNEUFLEX_PY_DEV:-}" ] && profile=()
VIRTUAL_ENV="$PWD/.venv" .venv/bin/maturin develop "${profile[@]}" --quiet -m crates/python/Cargo.toml
[ -n "${PNEUFLEX_MUJOCO_PLUGIN:-}" ] || cargo build --release --quiet -p pneuflex-mujoco
.venv/bin/python crates/python/tests/test_bindings.py
exec .venv/bin/python crates/python/tests/test_mujoco_plugin.py
