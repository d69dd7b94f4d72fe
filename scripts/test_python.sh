#!/usr/bin/env bash
# Tests of the Python bindings (crates/python) and of the MuJoCo equivalent model (crossval/):
# creates/updates .venv (scripts/venv), builds and installs the bindings (scripts/build_python: release, or dev with PNEUFLEX_PY_DEV=1), runs
# crates/python/tests/test_bindings.py, then the MuJoCo plugins' tests (crates/python/tests/test_mujoco_plugin.py and
# test_mujoco_muscle_plugin.py;
# the plugin built in release unless PNEUFLEX_MUJOCO_PLUGIN names a build), then the wheel installed outside the
# repository (scripts/test_wheel). Exit status non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/venv
scripts/build_python
[ -n "${PNEUFLEX_MUJOCO_PLUGIN:-}" ] || cargo build --release --quiet -p pneuflex-mujoco
.venv/bin/python crates/python/tests/test_bindings.py
.venv/bin/python crates/python/tests/test_mujoco_plugin.py
.venv/bin/python crates/python/tests/test_mujoco_muscle_plugin.py
# The wheel where users install it: a fresh venv, an empty directory, every documented snippet and example
# against what the docs print (scripts/test_wheel; ~1.5 min in CI, most of it the wheel's build).
exec scripts/test_wheel
