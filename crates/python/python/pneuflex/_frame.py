"""The frame of ``render_mode="rgb_array"``: the force and position traces of an episode as an RGB image, drawn
with numpy alone (no plotting library): the force panel on top (f_ref grey, f_e blue), the position panel
below (x - x_e, green), each scaled to its own range, time left to right."""

from __future__ import annotations

import numpy as np

WIDTH, HEIGHT = 480, 320
_GREY, _BLUE, _GREEN, _AXIS = (150, 150, 150), (31, 119, 180), (44, 160, 44), (60, 60, 60)


def _line(img: np.ndarray, top: int, height: int, values: np.ndarray, lo: float, hi: float, colour) -> None:
    """Draws ``values`` (one per column) into the rows top..top+height as a connected line."""
    rows = top + height - 1 - np.round((values - lo) / (hi - lo) * (height - 1)).astype(int)
    rows = np.clip(rows, top, top + height - 1)
    prev = np.concatenate([rows[:1], rows[:-1]])
    for c, (a, b) in enumerate(zip(np.minimum(rows, prev), np.maximum(rows, prev))):
        img[a:b + 1, c] = colour


def _range(*series: np.ndarray, floor: float) -> tuple[float, float]:
    lo = min(float(s.min()) for s in series)
    hi = max(float(s.max()) for s in series)
    mid, half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 0.5 * floor) * 1.1
    return mid - half, mid + half


def traces(f_ref_n: np.ndarray, f_e_n: np.ndarray, x_mm: np.ndarray, width: int = WIDTH,
           height: int = HEIGHT) -> np.ndarray:
    """An (height, width, 3) uint8 frame of the traces (equal-length 1-D arrays; an empty episode is a blank
    frame with its axes). The force panel spans at least 1 N, the position panel at least 1 mm."""
    img = np.full((height, width, 3), 255, np.uint8)
    half = height // 2
    for top in (0, half):
        img[top + half - 1, :] = _AXIS
        img[top:top + half, 0] = _AXIS
    if len(f_e_n) == 0:
        return img
    # One value per column: the samples resampled onto the frame's width.
    at = np.linspace(0, len(f_e_n) - 1, width)
    idx = np.arange(len(f_e_n))
    f_ref, f_e, x = (np.interp(at, idx, np.asarray(s, float)) for s in (f_ref_n, f_e_n, x_mm))
    lo, hi = _range(f_ref, f_e, floor=1.0)
    _line(img, 2, half - 4, f_ref, lo, hi, _GREY)
    _line(img, 2, half - 4, f_e, lo, hi, _BLUE)
    lo, hi = _range(x, floor=1.0)
    _line(img, half + 2, half - 4, x, lo, hi, _GREEN)
    return img
