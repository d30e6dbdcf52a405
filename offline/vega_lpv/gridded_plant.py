"""Generalised plant on a grid of the scheduling parameter: the input of the LPV synthesis.

The plant is the weighted interconnection P(ρ) of thesis Eq. 4.2 at the grid values ρ_i, with
inputs ordered [w; u] (n_w exogenous, n_u controls) and outputs ordered [e; y] (n_e performance,
n_y measurements):

    ẋ = A x + B1 w + B2 u,   e = C1 x + D11 w + D12 u,   y = C2 x + D21 w + D22 u.

Nothing here is specific to the launcher; docs/LPV_SYNTHESIS.md §0 describes the
VEGA instance (ρ = v_x, nine grid points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PlantDataError", "PlantPoint", "GriddedPlant"]


class PlantDataError(ValueError):
    """Malformed or unusable plant data."""


def _as_float_array(name, value, ndim):
    """``value`` as a finite float array with ``ndim`` dimensions (a copy)."""
    array = np.array(value, dtype=float)
    if array.ndim != ndim:
        raise PlantDataError(f"{name} must have {ndim} dimensions, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise PlantDataError(f"{name} contains non-finite values")
    return array


def _check_sizes(n_w, n_u, n_e, n_y):
    """The partition sizes as ints; every channel group must be non-empty."""
    sizes = {"n_w": n_w, "n_u": n_u, "n_e": n_e, "n_y": n_y}
    for name, size in sizes.items():
        if int(size) != size or size < 1:
            raise PlantDataError(f"{name} must be a positive integer, got {size!r}")
    return tuple(int(size) for size in sizes.values())


def _check_shapes(A, B, C, D, n_w, n_u, n_e, n_y):
    """Shapes (…, n, n), (…, n, n_w+n_u), (…, n_e+n_y, n), (…, n_e+n_y, n_w+n_u)."""
    n = A.shape[-1]
    expected = {"A": (n, n), "B": (n, n_w + n_u), "C": (n_e + n_y, n), "D": (n_e + n_y, n_w + n_u)}
    for name, matrix in zip("ABCD", (A, B, C, D)):
        if matrix.shape[-2:] != expected[name]:
            raise PlantDataError(
                f"{name} has shape {matrix.shape[-2:]} per point, expected {expected[name]} "
                f"(n_x={n}, n_w={n_w}, n_u={n_u}, n_e={n_e}, n_y={n_y})")


@dataclass(frozen=True)
class PlantPoint:
    """The generalised plant frozen at one value of ρ (inputs [w; u], outputs [e; y]).

    Parameters
    ----------
    A, B, C, D : array_like
        State-space matrices, shapes (n, n), (n, n_w+n_u), (n_e+n_y, n), (n_e+n_y, n_w+n_u).
    n_w, n_u, n_e, n_y : int
        Partition sizes: exogenous inputs, controls, performance outputs, measurements.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    n_w: int
    n_u: int
    n_e: int
    n_y: int

    def __post_init__(self):
        sizes = _check_sizes(self.n_w, self.n_u, self.n_e, self.n_y)
        matrices = [_as_float_array(name, getattr(self, name), 2) for name in "ABCD"]
        _check_shapes(*matrices, *sizes)
        for name, value in zip(("A", "B", "C", "D", "n_w", "n_u", "n_e", "n_y"),
                               (*matrices, *sizes)):
            object.__setattr__(self, name, value)

    @property
    def n_x(self):
        """Number of plant states."""
        return self.A.shape[0]


@dataclass(frozen=True)
class GriddedPlant:
    """The generalised plant P(ρ_i) on an increasing grid ρ_1 < … < ρ_N (thesis Eq. 4.2).

    Parameters
    ----------
    rho : array_like, shape (N,)
        Grid values of the scheduling parameter, strictly increasing.
    A, B, C, D : array_like
        State-space matrices at each grid value, in one common state basis; shapes (N, n, n),
        (N, n, n_w+n_u), (N, n_e+n_y, n), (N, n_e+n_y, n_w+n_u).
    n_w, n_u, n_e, n_y : int
        Partition sizes of the inputs [w; u] and outputs [e; y].
    N : array_like, optional
        Rate term, shape (N, n, n): the plant is ẋ = (A + ρ̇ N) x + … at the grid values —
        what a ρ-dependent state transformation of a model adds along a trajectory
        (ρ̇ (dT⁻¹/dρ) T). None: no such term.

    Raises
    ------
    PlantDataError
        On wrong shapes, non-finite values or a grid that is not strictly increasing.
    """

    rho: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    n_w: int
    n_u: int
    n_e: int
    n_y: int
    N: np.ndarray | None = None

    def __post_init__(self):
        sizes = _check_sizes(self.n_w, self.n_u, self.n_e, self.n_y)
        if self.N is not None:
            N = _as_float_array("N", self.N, 3)
            if N.shape != np.shape(self.A):
                raise PlantDataError(f"N has shape {N.shape}, expected that of A "
                                     f"{np.shape(self.A)}")
            object.__setattr__(self, "N", N)
        rho = _as_float_array("rho", self.rho, 1)
        if rho.size == 0:
            raise PlantDataError("rho must hold at least one grid value")
        if np.any(np.diff(rho) <= 0.0):
            raise PlantDataError("rho must be strictly increasing")
        matrices = [_as_float_array(name, getattr(self, name), 3) for name in "ABCD"]
        for name, matrix in zip("ABCD", matrices):
            if matrix.shape[0] != rho.size:
                raise PlantDataError(
                    f"{name} holds {matrix.shape[0]} grid points, rho holds {rho.size}")
        _check_shapes(*matrices, *sizes)
        for name, value in zip(("rho", "A", "B", "C", "D", "n_w", "n_u", "n_e", "n_y"),
                               (rho, *matrices, *sizes)):
            object.__setattr__(self, name, value)

    @classmethod
    def from_points(cls, rho, points):
        """Stack :class:`PlantPoint` objects (all with the same sizes) into a grid."""
        points = list(points)
        if not points:
            raise PlantDataError("points must not be empty")
        first = points[0]
        sizes = (first.n_w, first.n_u, first.n_e, first.n_y)
        if any((p.n_w, p.n_u, p.n_e, p.n_y) != sizes for p in points):
            raise PlantDataError("all points must have the same partition sizes")
        if any(p.A.shape != first.A.shape for p in points):
            raise PlantDataError("all points must have the same number of states")
        return cls(rho, *(np.stack([getattr(p, name) for p in points]) for name in "ABCD"),
                   *sizes)

    @property
    def n_x(self):
        """Number of plant states."""
        return self.A.shape[1]

    @property
    def n_grid(self):
        """Number of grid points N."""
        return self.rho.size

    def point(self, i):
        """The plant at grid index ``i`` as a :class:`PlantPoint`."""
        return PlantPoint(self.A[i], self.B[i], self.C[i], self.D[i],
                          self.n_w, self.n_u, self.n_e, self.n_y)
