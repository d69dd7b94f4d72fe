"""The runner the binding tests share (plain asserts, no pytest in the venv): `@test` registers a test in file
order, `main()` runs them all, prints `ok`/`FAIL` per test and the count, and returns the exit status (non-zero
on any failure)."""

from __future__ import annotations

import traceback

TESTS = []


def test(f):
    TESTS.append(f)
    return f


def main() -> int:
    failed = 0
    for t in TESTS:
        try:
            t()
            print(f"ok   {t.__name__}")
        except Exception:
            failed += 1
            print(f"FAIL {t.__name__}")
            traceback.print_exc()
    print(f"{len(TESTS) - failed} passed, {failed} failed")
    return 1 if failed else 0
