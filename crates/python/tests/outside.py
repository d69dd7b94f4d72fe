"""The package as a user installs it, outside the repository (scripts/test_wheel): run with the Python of a fresh
venv that has the wheel installed, from an empty working directory. It runs every ```python block of
docs/gymnasium.md and docs/mujoco-plugin.md and every file of crates/python/examples/ (the commands the docs
give), and compares what each prints with the ```text block the docs put after it ("Prints:"), exactly. Plain
asserts; prints each check; non-zero exit on any failure.

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
    examples = sorted((REPO / "crates/python/examples").glob("*.py"))
    documented = {m for doc in DOCS for m in re.findall(r"crates/python/examples/(\w+\.py)", (REPO / doc).read_text())}
    for ex in examples:
        results.append(ex.name in documented)
        print(f"{'ok  ' if ex.name in documented else 'FAIL'} {ex.name} is run by a documented command")
    print(f"{sum(results)} passed, {len(results) - sum(results)} failed")
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
