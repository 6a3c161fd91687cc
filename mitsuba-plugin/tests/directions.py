"""Direction sets shared by the comparison tests (Mitsuba's local frame: z = normal)."""

import math

THETAS = (0.05, 0.3, 0.7, 1.1, 1.4)          # radians; cos from 0.997 down to 0.17
PHIS = (0.0, 1.3, 2.9, 4.4)


def hemisphere_grid(thetas=THETAS, phis=PHIS):
    return [(math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)) for t in thetas for p in phis]


def pairs():
    """(viewer, light) pairs: Mitsuba's si.wi and wo (Lacquer's wo and wi)."""
    grid = hemisphere_grid()
    return [(v, l) for v in grid for l in grid]


def rel_err(a, b, floor):
    """|a - b| relative to |b|, with values below `floor` compared absolutely against it."""
    return abs(a - b) / max(abs(b), floor)
