"""The package as a user installs it, outside the repository (scripts/test_wheel): run with the Python of a fresh
venv that has the wheel installed, from an empty working directory. It runs every ```python block of
docs/gymnasium.md and docs/mujoco-plugin.md and every file of crates/python/examples/ (the commands the docs
give), and compares what each prints with the ```text block the docs put after it ("Prints:"), exactly; mypy
checks them, and a typed use of the package, against the installed stubs. Plain asserts; prints each check;
non-zero exit on any failure.

    python outside.py REPO        # cwd: an empty directory; REPO: the checkout (only its docs and examples are read)
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(sys.argv[1]).resolve()
DOCS = ("docs/gymnasium.md", "docs/mujoco-plugin.md")
BLOCK = re.compile(r"```(\w+)\n(.*?)```(?:\n+Prints:\n+```text\n(.*?)```)?", re.S)


def run(argv: list[str], what: str, want: str | None) -> bool:
    r = subprocess.run(argv, capture_output=True, text=True, timeout=600, cwd=os.getcwd())
    ok = r.returncode == 0 and (want is None or r.stdout.strip() == want.strip())
    print(f"{'ok  ' if ok else 'FAIL'} {what}")
    if not ok:
        print(f"--- exit {r.returncode}\n--- printed:\n{r.stdout}--- the docs say:\n{want}--- stderr:\n{r.stderr[-3000:]}")
    return ok


# What mypy must accept with the installed stubs (besides every documented block and example), and what it must
# refuse: a number where a scene goes.
TYPED = """
import pandas as pd
import pneuflex
r: pneuflex.Results = pneuflex.run("paper-fig3")
frame: pd.DataFrame = r.trace("adaptive")
names: list[str] = pneuflex.Controller.from_scene("paper-fig3", "adaptive").signals
shipped: list[str] = pneuflex.scenes()
plugin: str = pneuflex.mujoco_plugin_path()
mjcf: str = pneuflex.mjcf("cylinder")
"""
UNTYPED = """
import pneuflex
pneuflex.run(42)
"""


def typecheck(repo: Path) -> bool:
    """mypy on the documented blocks, the examples and TYPED: no error; on UNTYPED: the argument's type error."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for doc in DOCS:
            for i, (lang, code, _) in enumerate(BLOCK.findall((repo / doc).read_text())):
                if lang == "python":
                    (d / f"{Path(doc).stem.replace('-', '_')}_{i}.py").write_text(code)
        for ex in (repo / "crates/python/examples").glob("*.py"):
            (d / ex.name).write_text(ex.read_text())
        (d / "typed.py").write_text(TYPED)
        bad = d / "bad" / "untyped.py"
        bad.parent.mkdir()
        bad.write_text(UNTYPED)
        mypy = [sys.executable, "-m", "mypy", "--ignore-missing-imports", "--no-error-summary",
                "--cache-dir", str(d / ".cache")]
        good = subprocess.run([*mypy, *sorted(str(p) for p in d.glob("*.py"))], capture_output=True, text=True)
        refused = subprocess.run([*mypy, str(bad)], capture_output=True, text=True)
    ok_good = good.returncode == 0 and not good.stdout.strip()
    ok_bad = refused.returncode == 1 and 'Argument 1 to "run" has incompatible type "int"' in refused.stdout
    print(f"{'ok  ' if ok_good else 'FAIL'} mypy accepts the documented blocks, the examples and the typed uses")
    print(f"{'ok  ' if ok_bad else 'FAIL'} mypy refuses pneuflex.run(42)")
    if not ok_good:
        print(good.stdout, good.stderr)
    if not ok_bad:
        print(refused.stdout, refused.stderr)
    return ok_good and ok_bad


def main() -> int:
    import pneuflex

    # The installed package, not the checkout: its data, its plugin.
    here = Path(pneuflex.__file__).resolve().parent
    assert REPO not in here.parents, f"pneuflex imported from the checkout: {here}"
    assert not list(Path.cwd().iterdir()), "the working directory is not empty"
    plugin = Path(pneuflex.mujoco_plugin_path())
    assert here in plugin.parents, f"mujoco_plugin_path() is not in the installed package: {plugin}"
    print(f"ok   pneuflex from {here}, the MuJoCo plugin {plugin.name} inside it, {len(pneuflex.scenes())} scenes")
    results = []
    for doc in DOCS:
        text = (REPO / doc).read_text()
        for i, (lang, code, want) in enumerate(BLOCK.findall(text)):
            if lang == "python":
                results.append(run([sys.executable, "-c", code], f"{doc} python block {i}", want or None))
            elif lang == "sh" and want:
                # A documented example command: python crates/python/examples/<file> [args], the file from the checkout.
                cmd = code.strip().split()
                assert cmd[0] == "python" and cmd[1].startswith("crates/python/examples/"), code
                results.append(run([sys.executable, str(REPO / cmd[1]), *cmd[2:]], f"{doc}: {code.strip()}", want))
    results.append(typecheck(REPO))
    examples = sorted((REPO / "crates/python/examples").glob("*.py"))
    documented = {m for doc in DOCS for m in re.findall(r"crates/python/examples/(\w+\.py)", (REPO / doc).read_text())}
    for ex in examples:
        results.append(ex.name in documented)
        print(f"{'ok  ' if ex.name in documented else 'FAIL'} {ex.name} is run by a documented command")
    print(f"{sum(results)} passed, {len(results) - sum(results)} failed")
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
