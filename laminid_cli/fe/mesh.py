"""Structured meshes of 8-node serendipity quadrilaterals on the rectangle [0, a] x [0, b].

Node order inside an element (counter-clockwise, as in most FE texts)::

    3 --- 6 --- 2        corners 0..3 at (xi, eta) = (-1,-1), (1,-1), (1,1), (-1,1)
    |           |        mid-sides 4..7 at (0,-1), (1,0), (0,1), (-1,0)
    7           5
    |           |
    0 --- 4 --- 1

x runs along side a, y along side b (README, "Conventions").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laminid_cli import memory
from laminid_cli.errors import ModelError
from laminid_cli.memory import format_bytes


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


#: fewest elements per side accepted from a user (a 1-element side has no interior node and
#: a clamped or supported edge then holds the whole plate)
MIN_ELEMENTS_PER_SIDE = 2
#: most elements per side accepted from a user
MAX_ELEMENTS_PER_SIDE = 200
#: elements longer than this many times their width are refused (the model is then
#: meaningless across them)
MAX_ELEMENT_ASPECT = 20.0


#: factorisations of K - sigma M (banded size) an identification holds at its peak; measured
#: peak resident memory of ``identify`` on S1.1 with the banded Cholesky (stop 23): 12x12
#: 187 MB, 16x16 278, 24x24 561, 32x32 1019 (the model part and up to 1.9 factors)
FACTORS_IDENTIFY = 2.2
#: the same for a Monte Carlo's calling process (the trial model's kept factorisations, the
#: trials' own, their bases): 12x12 304 MB, 16x16 738 (200 trials), 24x24 1740 (up to 17.6
#: factors) ...
FACTORS_MONTE_CARLO = 18.0
#: ... and what each further worker process adds (16x16, 200 trials: proportional set size of
#: the whole process tree 714 MB with -j 1, 914 MB with -j 2: ~7 factors)
FACTORS_PER_WORKER = 7.0


def monte_carlo_factors(jobs: int | None) -> float:
    """Factorisations held by a Monte Carlo in ``jobs`` processes (None: the cores)."""
    import os

    jobs = int(jobs or os.cpu_count() or 1)
    return FACTORS_MONTE_CARLO + FACTORS_PER_WORKER * max(jobs - 1, 0)


def parse_mesh(text: str, copies: int = 1, factors: float = FACTORS_IDENTIFY,
               what: str = "") -> tuple[int, int]:
    """``"12x12"`` -> (12, 12); ``"16"`` -> (16, 16).

    Raises ModelError on nonsense, on a degenerate mesh (fewer than
    :data:`MIN_ELEMENTS_PER_SIDE` elements on a side) and on a mesh whose model (``copies`` of
    it, one per worker process) would not fit in the memory of this machine
    (:func:`check_mesh_memory`, with ``factors`` and ``what``; default: an identification's).
    """
    nx, ny = mesh_elements(text)
    check_mesh_memory(nx, ny, copies=copies, factors=factors, what=what)
    return nx, ny


def mesh_elements(text: str) -> tuple[int, int]:
    """The elements (nx, ny) of a mesh written as ``text`` ("12x12", "16"), without the memory
    check of :func:`parse_mesh`: ModelError on nonsense, a degenerate or a too fine mesh. The
    command line's --mesh is checked with it as it is parsed (_common.mesh_option)."""
    parts = str(text).lower().replace("*", "x").split("x")
    try:
        nums = [int(p) for p in parts]
    except ValueError:
        nums = []
    if len(nums) == 1:
        nums = nums * 2
    if len(nums) != 2 or min(nums) < 0:
        raise ModelError(f"mesh '{text}' not understood: give elements along x and y as NXxNY, "
                         "e.g. 12x12")
    if min(nums) < MIN_ELEMENTS_PER_SIDE:
        raise ModelError(f"mesh '{text}' is degenerate: at least {MIN_ELEMENTS_PER_SIDE} "
                         f"elements per side are needed (the paper uses 12x12)")
    if max(nums) > MAX_ELEMENTS_PER_SIDE:
        raise ModelError(f"mesh '{text}' is too fine (at most {MAX_ELEMENTS_PER_SIDE} elements "
                         "per side)")
    return nums[0], nums[1]


def model_memory_bytes(nx: int, ny: int, factors: float = FACTORS_IDENTIFY) -> float:
    """Estimated peak memory (bytes) of an identification on an nx x ny mesh, holding
    ``factors`` factorisations of K - sigma M at once (FACTORS_IDENTIFY; a Monte Carlo
    :func:`monte_carlo_factors`).

    9 unknowns per node; the assembled stiffness basis and mass about 18 kB per equation, plus
    100 MB; a banded Cholesky factor holds (bandwidth + 1) values per equation, with
    bandwidth + 1 = 9 (3 min(nx, ny) + 5) after node-wise reverse Cuthill-McKee. CHOLMOD's
    factor (modal.SparseCholesky, used when cvxopt is installed) is smaller (24x24: 33 against
    91 MB), so the estimate is an upper bound with either: fitted to the peaks measured with
    the banded one (the constants' comments; with CHOLMOD: identify 24x24 488 MB, 32x32 767 MB;
    Monte Carlo 16x16 -j 2 613 MB against 914 MB banded). Until stop 23 it counted ~1.1
    factors, below identify's peaks (670 MB at 24x24 then, against 496 estimated).
    """
    n_eq = 9 * ((2 * nx + 1) * (2 * ny + 1) - nx * ny)
    band = 9 * (3 * min(nx, ny) + 5)
    return 100e6 + n_eq * (18_000.0 + 8.0 * band * factors)


def check_mesh_memory(nx: int, ny: int, copies: int = 1,
                      available: float | None = None,
                      factors: float = FACTORS_IDENTIFY, what: str = "") -> None:
    """Raise ModelError when ``copies`` models on an nx x ny mesh would not fit in memory.

    The message gives the estimate (:func:`model_memory_bytes` with ``factors``; ``what``
    names the work, e.g. " with the Monte Carlo trials"), the memory available and the largest
    mesh of the same shape that fits.
    """
    available = memory.available_memory_bytes() if available is None else available
    need = copies * model_memory_bytes(nx, ny, factors)
    if available is None or need <= available:
        return
    fits = None
    longest = max(nx, ny)
    for k in range(longest - 1, 0, -1):      # same shape, one element fewer on the long side
        mx, my = max(1, round(nx * k / longest)), max(1, round(ny * k / longest))
        if copies * model_memory_bytes(mx, my, factors) <= available:
            fits = (mx, my)
            break
    many = f" for {copies} worker processes" if copies > 1 else ""
    hint = (f"the largest {'mesh' if nx == ny else 'mesh of this shape'} that fits is "
            f"{fits[0]}x{fits[1]}" if fits and min(fits) >= MIN_ELEMENTS_PER_SIDE
            else "no usable mesh fits")
    raise ModelError(f"mesh {nx}x{ny} needs about {format_bytes(need)} of memory{what}{many}, "
                     f"and {format_bytes(available)} is available: {hint}")


def check_element_shape(a: float, b: float, nx: int, ny: int) -> None:
    """Raise ModelError when the elements are more than :data:`MAX_ELEMENT_ASPECT` times longer
    than wide (a degenerate mesh for this plate)."""
    ex, ey = a / nx, b / ny
    ratio = max(ex / ey, ey / ex)
    if ratio > MAX_ELEMENT_ASPECT:
        better = (max(MIN_ELEMENTS_PER_SIDE, round(ny * a / b)), ny) if ex > ey else \
            (nx, max(MIN_ELEMENTS_PER_SIDE, round(nx * b / a)))
        raise ModelError(f"mesh {nx}x{ny} on a {a * 1e3:g} x {b * 1e3:g} mm plate makes "
                         f"elements {ratio:.3g} times longer than wide (at most "
                         f"{MAX_ELEMENT_ASPECT:g}); use e.g. {better[0]}x{better[1]}")


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
