"""Figures checked by what they show, not by their file size: a PNG read back with matplotlib
is an image of the expected size, not blank, with axes frames and coloured data on them."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _long_runs(mask: np.ndarray, length: float) -> np.ndarray:
    """Per row of ``mask``: how many runs of True are longer than ``length``."""
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), np.int8)
    padded[:, 1:-1] = mask
    edges = np.diff(padded, axis=1)
    counts = np.zeros(mask.shape[0], int)
    for i, row in enumerate(edges):
        starts, ends = np.flatnonzero(row == 1), np.flatnonzero(row == -1)
        counts[i] = int(np.sum(ends - starts > length))
    return counts


def count_panels(rgb: np.ndarray) -> int:
    """Axes frames in an image: straight dark horizontal lines longer than a tenth of the width
    (a frame's top and bottom spines), side by side or stacked, halved."""
    height, width = rgb.shape[:2]
    dark = np.all(rgb < 0.35, axis=-1)
    counts = _long_runs(dark, width / 10)
    rows = np.flatnonzero(counts)
    if rows.size == 0:
        return 0
    groups = np.split(rows, np.flatnonzero(np.diff(rows) > 2) + 1)  # a spine may be 2-3 pixels thick
    return sum(int(counts[g].max()) for g in groups) // 2


def assert_drawn(path: str | Path, *, panels: int = 1, min_pixels: tuple[int, int] = (200, 300)) -> np.ndarray:
    """Assert that ``path`` is a drawn matplotlib figure and return its pixels (H, W, channels).

    - it reads back as a PNG of at least ``min_pixels`` (height, width);
    - it is not blank: at least 2 % of the pixels differ from the background (the corner colour);
    - it shows at least ``panels`` axes (:func:`count_panels`: their frames' spines);
    - its data are drawn in colour: at least 0.1 % of the pixels are saturated (not grey), as
      matplotlib's default line and marker colours are.
    """
    import matplotlib.image as mpimg

    path = Path(path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f"{path}: not a PNG"
    image = mpimg.imread(path)
    assert image.ndim == 3 and image.shape[2] in (3, 4), f"{path}: not an RGB(A) image ({image.shape})"
    rgb = image[..., :3].astype(float)
    height, width = rgb.shape[:2]
    assert height >= min_pixels[0] and width >= min_pixels[1], f"{path}: only {width}x{height} pixels"
    background = rgb[0, 0]
    drawn = np.any(np.abs(rgb - background) > 0.05, axis=-1)
    assert drawn.mean() > 0.02, f"{path}: blank ({100 * drawn.mean():.2f} % of the pixels drawn)"
    found = count_panels(rgb)
    assert found >= panels, f"{path}: expected {panels} axes, found {found}"
    saturation = rgb.max(axis=-1) - rgb.min(axis=-1)
    assert (saturation > 0.25).mean() > 0.001, f"{path}: no coloured data drawn"
    return image
