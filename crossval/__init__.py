"""MuJoCo cross-validation of pneuflex scenes: `python -m crossval [scene ...]` (docs/crossval.md)."""
