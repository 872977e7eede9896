"""Least squares of a sum of rotating vectors on one laser's rows, in bounded memory.

One laser of a table fires at uniform times ``t_n = t0 + n dt`` (n < N). Its
values ``z_n`` (complex degrees) are fitted by ``sum_j c_j exp(i 2 pi f_j t_n)``
for given frequencies f_j through the normal equations:

- the Gram matrix ``G[a, b] = sum_n exp(i 2 pi (f_b - f_a) t_n)`` is a geometric
  series, summed in closed form (a Dirichlet kernel): no design matrix;
- the projections ``sum_n z_n exp(-i 2 pi f_a t_n)`` and the model are made
  block by block: rows are cut into blocks of B samples, a block's phasors are
  a fixed ``(J, B)`` table times each term's phasor at the block start, so both
  are matrix products, and memory is O(N + J (B + N / B)) whatever J.

Frequencies closer than about 1 / (N dt) cannot be told apart by the rows and
make ``G`` singular: callers keep their terms apart (:func:`resolvable`), and
the solve falls back to a minimum-norm least squares if ``G`` is not positive
definite.
"""

from __future__ import annotations

import math

import numpy as np

_BLOCK = 2048


class LaserRows:
    """One laser's uniformly spaced rows.

    Parameters
    ----------
    z : (N,) complex128
        Values, degrees.
    t0 : float
        Time of the first row, seconds.
    dt : float
        Spacing of the rows, seconds.
    """

    def __init__(self, z: np.ndarray, t0: float, dt: float) -> None:
        z = np.asarray(z, dtype=np.complex128)
        self.n = int(z.size)
        self.t0 = float(t0)
        self.dt = float(dt)
        self.block = max(1, min(_BLOCK, self.n))
        blocks = -(-self.n // self.block)
        padded = np.zeros(blocks * self.block, dtype=np.complex128)
        padded[: self.n] = z
        self.blocks = padded.reshape(blocks, self.block)

    @property
    def z(self) -> np.ndarray:
        """``(N,)`` complex128 the values (a view)."""
        return self.blocks.reshape(-1)[: self.n]

    @property
    def span(self) -> float:
        """Seconds from the first row to the last."""
        return (self.n - 1) * self.dt

    def _basis(self, hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ``(J, B)`` in-block phasor table and ``(blocks, J)`` block-start phasors."""
        within = np.arange(self.block, dtype=np.float64) * self.dt
        table = np.exp(2j * np.pi * np.mod(np.outer(hz, within), 1.0))
        starts = self.t0 + np.arange(self.blocks.shape[0], dtype=np.float64) * (self.block * self.dt)
        start_phasors = np.exp(2j * np.pi * np.mod(np.outer(starts, hz), 1.0))
        return table, start_phasors

    def gram(self, hz: np.ndarray) -> np.ndarray:
        """``(J, J)`` complex128 ``sum_n exp(i 2 pi (f_b - f_a) t_n)``, in closed form."""
        delta = hz[None, :] - hz[:, None]
        cycles = np.mod(delta * self.dt + 0.5, 1.0) - 0.5
        denominator = np.sin(np.pi * cycles)
        tiny = np.abs(denominator) < 1e-12
        with np.errstate(divide="ignore", invalid="ignore"):
            kernel = np.where(tiny, float(self.n), np.sin(np.pi * cycles * self.n) / np.where(tiny, 1.0, denominator))
        phase = np.pi * cycles * (self.n - 1) + 2 * np.pi * np.mod(delta * self.t0, 1.0)
        return kernel * np.exp(1j * phase)

    def project(self, hz: np.ndarray, basis: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """``(J,)`` complex128 ``sum_n z_n exp(-i 2 pi f_a t_n)``."""
        table, start_phasors = basis if basis is not None else self._basis(hz)
        per_block = self.blocks @ table.conj().T
        return np.einsum("bj,bj->j", start_phasors.conj(), per_block)

    def model(self, hz: np.ndarray, coefficients: np.ndarray,
              basis: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """``(N,)`` complex128 the series at the rows' times."""
        table, start_phasors = basis if basis is not None else self._basis(hz)
        return ((start_phasors * coefficients[None, :]) @ table).reshape(-1)[: self.n]

    def solve(self, hz: np.ndarray, residual: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Least-squares coefficients ``(J,)`` for frequencies ``hz`` (cycles/s), and the ``(N,)`` residual."""
        hz = np.asarray(hz, dtype=np.float64)
        basis = self._basis(hz)
        coefficients = solve_normal(self.gram(hz), self.project(hz, basis))
        if not residual:
            return coefficients, None
        return coefficients, self.z - self.model(hz, coefficients, basis)


def solve_normal(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve ``gram @ c = rhs`` for a Hermitian positive (semi)definite ``gram``: Cholesky, else least squares."""
    import scipy.linalg

    try:
        factor = scipy.linalg.cho_factor(gram, check_finite=False)
        solution = scipy.linalg.cho_solve(factor, rhs, check_finite=False)
        if np.all(np.isfinite(solution)):
            return solution
    except np.linalg.LinAlgError:
        pass
    return np.linalg.lstsq(gram, rhs, rcond=1e-12)[0]


def resolvable(hz: np.ndarray, order: np.ndarray, separation: float) -> np.ndarray:
    """``(J,)`` bool: keep each frequency unless one of lower ``order`` lies within ``separation`` of it.

    Parameters
    ----------
    hz : (J,) float64
    order : (J,) float or int
        Lower is preferred (kept first).
    separation : float
        Hz.
    """
    keep = np.zeros(hz.size, dtype=bool)
    kept: list[float] = []
    for index in np.lexsort((np.abs(hz), order)):
        frequency = float(hz[index])
        if all(abs(frequency - other) >= separation for other in kept):
            keep[index] = True
            kept.append(frequency)
    return keep


def rms(values: np.ndarray) -> float:
    """Root mean square of complex or real values."""
    values = np.asarray(values)
    return math.sqrt(float(np.mean(np.abs(values) ** 2))) if values.size else 0.0
