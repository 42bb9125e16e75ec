"""Colours for label ids, shared by previews and coloured PLY files."""

from __future__ import annotations

import numpy as np

from generator.scene.taxonomy import CLASS_COLORS

# for labels outside the taxonomy (arbitrary .blend files): a colour-blind-friendly cycle
_CYCLE = np.array([[230, 159, 0], [86, 180, 233], [0, 158, 115], [240, 228, 66], [0, 114, 178],
                   [213, 94, 0], [204, 121, 167], [120, 120, 120]], np.uint8)
UNLABELLED = (0, 0, 0)


def label_colors(labels: list[str]) -> np.ndarray:
    """(L, 3) uint8 RGB per label id: the taxonomy's class colour, else a fixed cycle."""
    return np.array([CLASS_COLORS.get(name, tuple(_CYCLE[i % len(_CYCLE)])) for i, name in enumerate(labels)],
                    np.uint8).reshape(-1, 3)


def colorize_labels(label_map: np.ndarray, labels: list[str]) -> np.ndarray:
    """(..., 3) uint8 image of a label map; -1 (unlabelled) is black."""
    colors = label_colors(labels)
    out = np.zeros(label_map.shape + (3,), np.uint8)
    ok = (label_map >= 0) & (label_map < len(colors))
    out[ok] = colors[label_map[ok]]
    return out
