"""Argument checks of the package's Python entry points (run, sweep, tune, identify, the Gymnasium environments).

A wrong type is a ``TypeError`` and a wrong value a ``ValueError``, each naming the function and the argument as
typed. Nothing is coerced with ``str()`` or ``int()``: ``str(42)`` would be looked up as a file named "42", and a
string where a list belongs would be read one character at a time.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Iterable, Mapping, Set

PathLike = (str, bytes, os.PathLike)


def kind(value) -> str:
    """The type and a short repr of ``value``, for messages."""
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 60 else text[:57] + '...'}"


def path(value, name: str, where: str) -> str:
    """A file or directory argument as a str: a str, bytes or os.PathLike, not empty."""
    if not isinstance(value, PathLike):
        raise TypeError(f"{where}: {name} must be a path (str or os.PathLike), got {kind(value)}")
    p = os.fsdecode(os.fspath(value))
    if not p:
        raise ValueError(f"{where}: {name} is an empty path")
    return p


def optional_path(value, name: str, where: str) -> str | None:
    return None if value is None else path(value, name, where)


def items(value, name: str, where: str, what: str) -> list:
    """The elements of a list-like argument (list, tuple, any ordered iterable); a mapping or a set (no order
    a user chose) and a number are refused."""
    if isinstance(value, (Mapping, Set, bytes)) or not isinstance(value, Iterable):
        raise TypeError(f"{where}: {name} must be a list of {what}, got {kind(value)}")
    return list(value)


def paths(value, name: str, where: str, nonempty: bool = False) -> list[str]:
    """One path or a list of paths (at least one when ``nonempty``)."""
    if isinstance(value, PathLike):
        return [path(value, name, where)]
    out = [path(v, f"{name}[{i}]", where) for i, v in enumerate(items(value, name, where, "paths"))]
    if nonempty and not out:
        raise ValueError(f"{where}: {name} is empty: give at least one path")
    return out


def strings(value, name: str, where: str, what: str, nonempty: bool = False) -> list[str]:
    """One string (a single entry) or a list of strings (at least one when ``nonempty``); every element must be
    a str."""
    if isinstance(value, str):
        return [value]
    out = items(value, name, where, what)
    for i, v in enumerate(out):
        if not isinstance(v, str):
            raise TypeError(f"{where}: {name}[{i}] must be a str ({what}), got {kind(v)}")
    if nonempty and not out:
        raise ValueError(f"{where}: {name} is empty: give at least one of the {what}")
    return out


def optional_string(value, name: str, where: str) -> str | None:
    if value is None or isinstance(value, str):
        return value
    raise TypeError(f"{where}: {name} must be a str or None, got {kind(value)}")


def integer(value, name: str, where: str, minimum: int | None = None) -> int:
    """An int (a numpy integer too; not a bool, not a float, even a whole one) at least ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{where}: {name} must be an integer, got {kind(value)}")
    v = int(value)
    if minimum is not None and v < minimum:
        raise ValueError(f"{where}: {name} must be at least {minimum}, got {v}")
    return v


def optional_integer(value, name: str, where: str, minimum: int | None = None) -> int | None:
    return None if value is None else integer(value, name, where, minimum)


def seed(value, name: str, where: str) -> int:
    """A seed: an integer in [0, 2^64)."""
    v = integer(value, name, where, 0)
    if v >= 2**64:
        raise ValueError(f"{where}: {name} must be below 2^64, got {v}")
    return v


def number(value, name: str, where: str, ok=None, want: str = "") -> float:
    """A finite real number (int or float, not a bool) for which ``ok(v)`` holds (``want`` says what it must be)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{where}: {name} must be a number, got {kind(value)}")
    v = float(value)
    if not math.isfinite(v) or (ok is not None and not ok(v)):
        raise ValueError(f"{where}: {name} must be {want or 'finite'}, got {value!r}")
    return v


def flag(value, name: str, where: str) -> bool:
    """A bool (numpy's too); 1, "yes" and "false" are refused rather than read by their truth value."""
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        return bool(value)
    raise TypeError(f"{where}: {name} must be True or False, got {kind(value)}")
