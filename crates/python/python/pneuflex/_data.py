"""What the package ships (``pneuflex/data``, copied there at build time by ``scripts/stage_python_data``): the
scenes of ``scenes/`` with the actuator sheets (``pneumatics/``) and URDFs and meshes (``urdf/``) they name, in
the repository's layout, so that a scene's relative paths (``../pneumatics/paper-actuator.toml``) resolve inside
the installed package; the MJCF examples of ``pneuflex/mjcf``; the MuJoCo plugin library. A package built without
its data (``pip install ./crates/python`` from a checkout, not staged) reads the checkout it was built in, which
has the same layout."""

from __future__ import annotations

import os
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent


def _data() -> Path:
    """The package's data; in a package built without it (``pip install ./crates/python`` straight from a
    checkout, not staged), the checkout the extension was built in, whose layout is the same."""
    staged = PACKAGE / "data"
    if (staged / "scenes").is_dir():
        return staged
    from . import _native

    workspace = Path(getattr(_native, "_workspace_dir", staged)).resolve()
    return workspace if (workspace / "scenes").is_dir() else staged


#: The shipped files, in the repository's layout: scenes/, pneumatics/, urdf/.
DATA = _data()
SCENES = DATA / "scenes"


def scenes() -> list[str]:
    """The names of the shipped scenes (``"paper-fig3"`` for ``data/scenes/paper-fig3.toml``), sorted."""
    return sorted(p.stem for p in SCENES.glob("*.toml"))


def _looks_like_a_name(p: str) -> bool:
    return bool(p) and os.sep not in p and "/" not in p and not p.endswith(".toml")


def resolve(scene) -> str:
    """A scene argument as a file: an existing path as given; a name without a folder or ``.toml`` that is no
    file here (``"paper-fig3"``), the shipped scene's file; anything else as given (the loader then says the
    file is missing). An unknown name is a FileNotFoundError listing the shipped ones."""
    p = os.fsdecode(os.fspath(scene))
    if os.path.exists(p) or not _looks_like_a_name(p):
        return p
    shipped = SCENES / f"{p}.toml"
    if shipped.is_file():
        return str(shipped)
    names = scenes()
    if not names:
        raise FileNotFoundError(
            f"{p}: no such file, and this installation ships no scenes ({SCENES} is missing: a build of the package "
            "without scripts/stage_python_data)")
    raise FileNotFoundError(f"{p}: no such file, nor a shipped scene; the shipped scenes are {', '.join(names)}")
