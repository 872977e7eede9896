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

    @property
    def t(self) -> np.ndarray:
        """``(N,)`` each row's time, seconds."""
        return self.t0 + np.arange(self.n, dtype=np.float64) * self.dt

    def solve_terms(self, base_hz: tuple[float, float], terms: list[tuple[int, int]] | tuple[tuple[int, int], ...],
                    residual: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`solve` for the terms ``(m, l)`` at ``m f_A + l f_B`` (as :meth:`TimedRows.solve_terms`)."""
        return self.solve(np.array([m * base_hz[0] + n * base_hz[1] for m, n in terms], dtype=np.float64),
                          residual)

    def solve(self, hz: np.ndarray, residual: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Least-squares coefficients ``(J,)`` for frequencies ``hz`` (cycles/s), and the ``(N,)`` residual."""
        hz = np.asarray(hz, dtype=np.float64)
        basis = self._basis(hz)
        coefficients = solve_normal(self.gram(hz), self.project(hz, basis))
        if not residual:
            return coefficients, None
        return coefficients, self.z - self.model(hz, coefficients, basis)


class TimedRows:
    """One laser's rows at any times (a recording's rows with gaps, or lasers out of order), for frequencies on
    a lattice ``m f_A + l f_B``.

    The lattice makes every sum separable: with ``A_n = exp(i 2 pi f_A t_n)`` and ``B_n`` alike, the Gram
    matrix's entries are ``D[p, q] = sum_n A_n^p B_n^q`` for the differences (p, q) of two terms' orders (one
    ``(4 M_A + 1) x (4 M_B + 1)`` matrix product over the rows, M the largest orders), the projections are
    ``sum_n z_n A_n^-m B_n^-l`` and the model ``sum_m A_n^m (sum_l c_ml B_n^l)``, all matrix products over
    blocks of rows: memory O(rows + block x orders), never rows x terms.

    Parameters
    ----------
    z : (N,) complex128
        Values, degrees.
    t : (N,) float64
        Each row's time, seconds.
    """

    def __init__(self, z: np.ndarray, t: np.ndarray) -> None:
        self.z = np.asarray(z, dtype=np.complex128)
        self.t = np.asarray(t, dtype=np.float64)
        self.n = int(self.z.size)

    @property
    def span(self) -> float:
        """Seconds from the first row to the last."""
        return float(self.t[-1] - self.t[0]) if self.n > 1 else 0.0

    def _powers(self, rows: slice, hz: float, reach: int) -> np.ndarray:
        """``(rows, 2 reach + 1)`` ``exp(i 2 pi p hz t)`` for p = -reach .. reach: one exponential per row, its
        powers by products (a hundred products lose about 1e-14; an exponential each cost 20 x more)."""
        phasor = np.exp(2j * np.pi * np.mod(self.t[rows] * hz, 1.0))
        out = np.empty((phasor.size, 2 * reach + 1), dtype=np.complex128)
        out[:, reach] = 1.0
        if reach:
            rising = np.cumprod(np.repeat(phasor[:, None], reach, axis=1), axis=1)
            out[:, reach + 1 :] = rising
            out[:, :reach] = rising[:, ::-1].conj()
        return out

    def solve_terms(self, base_hz: tuple[float, float], terms: list[tuple[int, int]] | tuple[tuple[int, int], ...],
                    residual: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Least-squares coefficients ``(J,)`` of the terms ``(m, l)`` at base frequencies ``base_hz`` (Hz), and
        the ``(N,)`` residual."""
        m = np.array([term[0] for term in terms], dtype=np.int64)
        l_ = np.array([term[1] for term in terms], dtype=np.int64)
        reach_a, reach_b = int(np.abs(m).max()), int(np.abs(l_).max())
        differences = np.zeros((4 * reach_a + 1, 4 * reach_b + 1), dtype=np.complex128)
        projections = np.zeros((2 * reach_a + 1, 2 * reach_b + 1), dtype=np.complex128)
        for start in range(0, self.n, _BLOCK):
            rows = slice(start, min(self.n, start + _BLOCK))
            powers_a = self._powers(rows, base_hz[0], 2 * reach_a)
            powers_b = self._powers(rows, base_hz[1], 2 * reach_b)
            differences += powers_a.T @ powers_b
            inner_a = powers_a[:, reach_a : 3 * reach_a + 1]
            inner_b = powers_b[:, reach_b : 3 * reach_b + 1]
            projections += (inner_a.conj() * self.z[rows, None]).T @ inner_b.conj()
        gram = differences[m[None, :] - m[:, None] + 2 * reach_a, l_[None, :] - l_[:, None] + 2 * reach_b]
        coefficients = solve_normal(gram, projections[m + reach_a, l_ + reach_b])
        if not residual:
            return coefficients, None
        return coefficients, self.z - self.model(base_hz, terms, coefficients)

    def model(self, base_hz: tuple[float, float], terms: list[tuple[int, int]] | tuple[tuple[int, int], ...],
              coefficients: np.ndarray) -> np.ndarray:
        """``(N,)`` complex128 the series at the rows' times."""
        m = np.array([term[0] for term in terms], dtype=np.int64)
        l_ = np.array([term[1] for term in terms], dtype=np.int64)
        reach_a, reach_b = int(np.abs(m).max()), int(np.abs(l_).max())
        table = np.zeros((2 * reach_a + 1, 2 * reach_b + 1), dtype=np.complex128)
        table[m + reach_a, l_ + reach_b] = coefficients
        out = np.empty(self.n, dtype=np.complex128)
        for start in range(0, self.n, _BLOCK):
            rows = slice(start, min(self.n, start + _BLOCK))
            out[rows] = np.sum(self._powers(rows, base_hz[0], reach_a)
                               * (self._powers(rows, base_hz[1], reach_b) @ table.T), axis=1)
        return out


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
