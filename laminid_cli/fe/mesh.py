"""Structured meshes of 8-node serendipity quadrilaterals on the rectangle [0, a] x [0, b].

Node order inside an element (counter-clockwise, as in most FE texts)::

    3 --- 6 --- 2        corners 0..3 at (xi, eta) = (-1,-1), (1,-1), (1,1), (-1,1)
    |           |        mid-sides 4..7 at (0,-1), (1,0), (0,1), (-1,0)
    7           5
    |           |
    0 --- 4 --- 1

x runs along side a, y along side b (DESIGN.md section 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laminid_cli.errors import ModelError


@dataclass(frozen=True)
class Mesh:
    """A quadrilateral mesh.

    Attributes
    ----------
    nodes : float (n_nodes, 2), m
    elements : int (n_elements, 8), node indices in the order of the module docstring
    a, b : plate sides along x and y, m
    nx, ny : elements along x and y
    """

    nodes: np.ndarray
    elements: np.ndarray
    a: float
    b: float
    nx: int
    ny: int

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_elements(self) -> int:
        return int(self.elements.shape[0])


def parse_mesh(text: str) -> tuple[int, int]:
    """``"12x12"`` -> (12, 12); ``"16"`` -> (16, 16). Raises ModelError on nonsense."""
    parts = str(text).lower().replace("*", "x").split("x")
    try:
        nums = [int(p) for p in parts]
    except ValueError:
        nums = []
    if len(nums) == 1:
        nums = nums * 2
    if len(nums) != 2 or min(nums) < 1:
        raise ModelError(f"mesh '{text}' not understood: give elements along x and y as NXxNY, "
                         "e.g. 12x12")
    if max(nums) > 200:
        raise ModelError(f"mesh '{text}' is too fine (at most 200 elements per side)")
    return nums[0], nums[1]


def rectangular_mesh(a: float, b: float, nx: int, ny: int) -> Mesh:
    """Regular nx x ny mesh of Q8 elements on [0, a] x [0, b].

    Nodes are numbered row by row (y outer, x inner) over the (2nx+1) x (2ny+1) grid of
    corner and mid-side points, skipping element centres.
    """
    if a <= 0 or b <= 0:
        raise ModelError(f"plate sides must be positive (a = {a} m, b = {b} m)")
    if nx < 1 or ny < 1:
        raise ModelError(f"mesh needs at least 1x1 elements (got {nx}x{ny})")
    gx, gy = 2 * nx + 1, 2 * ny + 1
    ii, jj = np.meshgrid(np.arange(gx), np.arange(gy))          # (gy, gx)
    keep = ~((ii % 2 == 1) & (jj % 2 == 1))                      # drop element centres
    index = -np.ones((gy, gx), dtype=np.int64)
    index[keep] = np.arange(keep.sum())
    nodes = np.column_stack([ii[keep] * (a / (2 * nx)), jj[keep] * (b / (2 * ny))])
    ex, ey = np.meshgrid(np.arange(nx), np.arange(ny))
    i0, j0 = (2 * ex).ravel(), (2 * ey).ravel()
    # (grid dx, grid dy) of the 8 nodes relative to the lower-left corner
    offsets = [(0, 0), (2, 0), (2, 2), (0, 2), (1, 0), (2, 1), (1, 2), (0, 1)]
    elements = np.column_stack([index[j0 + dj, i0 + di] for di, dj in offsets])
    return Mesh(nodes=nodes, elements=elements, a=float(a), b=float(b), nx=int(nx), ny=int(ny))
