"""The metric grid of the road plane a bird's-eye view (BEV) is drawn on: :class:`BevGrid`.

Axes (the KITTI road benchmark's, ``../shared/docs/method.md``'s world frame): x lateral, metres,
positive to the right of the camera; z forward along the road, metres from the point of the road
straight below the camera. A BEV array has shape (rows, cols) = (z cells, x cells); **row 0 is the
far edge** (z_max) as the devkit's ``BirdsEyeView``, column 0 the left edge (x_min). Cell (i, j)
covers x in [x_min + j*res, x_min + (j+1)*res) and z in (z_max - (i+1)*res, z_max - i*res]; its
centre is what is projected into the image.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["BevGrid", "MAX_CELLS", "KITTI_GRID", "parse_range"]

MAX_CELLS = 50_000_000  # a grid over this many cells is refused (0.05 m over 20 x 40 m: 320,000)


@dataclass(frozen=True)
class BevGrid:
    """x range (lateral), z range (forward) and cell size, all in metres. The default is the
    KITTI road benchmark's: x -10..10 m, z 6..46 m, 0.05 m cells (400 x 800 cells)."""

    x_min: float = -10.0  # left edge (m, negative = left of the camera)
    x_max: float = 10.0   # right edge (m)
    z_min: float = 6.0    # near edge (m ahead of the camera's foot on the road)
    z_max: float = 46.0   # far edge (m)
    res: float = 0.05     # cell size (m)

    def __post_init__(self) -> None:
        what = f"grid x {self.x_min:g}..{self.x_max:g} m, z {self.z_min:g}..{self.z_max:g} m, {self.res:g} m cells"
        if not all(np.isfinite([self.x_min, self.x_max, self.z_min, self.z_max, self.res])):
            raise InputError(f"{what}: not finite", None, "give finite metres")
        if not (self.res > 0 and self.x_max > self.x_min and self.z_max > self.z_min):
            raise InputError(f"{what}: empty", None, "give x_min < x_max, z_min < z_max and a resolution > 0")
        cells = float(self.x_max - self.x_min) / self.res * float(self.z_max - self.z_min) / self.res
        if cells > MAX_CELLS:
            raise InputError(f"{what} would have {cells / 1e6:,.0f} megacells, over the {MAX_CELLS // 1_000_000} "
                             f"megacell limit", None, "use a coarser --res or a smaller --range")
        if min(self.shape) < 1:
            raise InputError(f"{what}: less than one cell", None, "use a finer --res")

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) = (z cells, x cells), the devkit's rounding of extent / res."""
        return (int(round((self.z_max - self.z_min) / self.res)), int(round((self.x_max - self.x_min) / self.res)))

    def x_centres(self) -> np.ndarray:
        """(cols,) lateral cell centres, left to right (the devkit's ``arange`` from x_min + res/2)."""
        return np.arange(self.x_min + self.res / 2, self.x_max, self.res)[: self.shape[1]]

    def z_centres(self) -> np.ndarray:
        """(rows,) forward cell centres, FAR FIRST (the devkit's ``arange`` from z_max - res/2 down)."""
        return np.arange(self.z_max - self.res / 2, self.z_min, -self.res)[: self.shape[0]]

    def row_at(self, z: float) -> int | None:
        """The row whose z interval holds ``z`` metres ahead; None outside the grid."""
        if not (self.z_min <= z <= self.z_max):
            return None
        return int(min(self.shape[0] - 1, max(0, np.floor((self.z_max - z) / self.res))))

    def to_dict(self) -> dict[str, float]:
        return {"x": [self.x_min, self.x_max], "z": [self.z_min, self.z_max], "res": self.res}


KITTI_GRID = BevGrid()


def parse_range(text: str | None, res: float | None = None) -> BevGrid:
    """``--range 'X0,X1,Z0,Z1'`` (metres; None: the KITTI benchmark's) and ``--res`` (None: 0.05)."""
    base = KITTI_GRID
    if text is None:
        x0, x1, z0, z1 = base.x_min, base.x_max, base.z_min, base.z_max
    else:
        try:
            x0, x1, z0, z1 = (float(v) for v in text.replace(" ", "").split(","))
        except ValueError:
            raise InputError(f"--range '{text}' is not four numbers X0,X1,Z0,Z1", None,
                             "give lateral then forward extent in metres, e.g. --range=-10,10,6,46") from None
    return BevGrid(x0, x1, z0, z1, base.res if res is None else float(res))
