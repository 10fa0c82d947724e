r"""Task-space attractor dynamics: one attractor point per GMM component, linear in the points.

Each task dimension follows the critically damped system :math:`\ddot x = \omega^2 (r - x) -
2\omega \dot x` towards a piecewise-constant target :math:`r_t = a_k` while step ``t`` lies in
component ``k``'s interval (hard switches at the midpoints between the sorted time means of the
components). The system is discretised exactly (zero-order hold on ``r``):
:math:`s_{t+1} = A_d s_t + B_d r_t`, :math:`s = (x, \dot x)`. Hence the whole trajectory is

.. math:: x_{0:T} = S_x s_0 + \Psi a, \qquad \partial x_t / \partial a_k = \Psi_{t,k} I_m,

with the ``(T+1, 2)`` free response ``S_x`` and the ``(T+1, K)`` matrix ``Psi`` computed once.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.linalg import expm

from imitate.errors import ImitateError

__all__ = ["AttractorDynamics"]


@functools.lru_cache(maxsize=64)
def _zero_order_hold(omega: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A_d (2, 2), B_d (2,))`` of the critically damped system over one step ``dt`` [s].
    Kept per ``(omega, dt)``: an evaluation plans many times with one model, and each
    ``scipy.linalg.expm`` call wakes OpenBLAS's worker threads, which then spin on the other
    cores for about 0.1 s of processor time."""
    M = np.array([[0.0, 1.0], [-omega**2, -2.0 * omega]])
    A = expm(M * dt)
    B = np.linalg.solve(M, (A - np.eye(2)) @ np.array([0.0, omega**2]))
    A.flags.writeable = B.flags.writeable = False
    return A, B


class AttractorDynamics:
    """Precomputed linear map from attractor points to the task trajectory.

    Args:
        n_steps: Number of steps ``T``; the trajectory has ``T + 1`` samples, ``x_0`` the start.
        dt: Step [s].
        centres: Time means of the GMM components [s], shape ``(K,)``, any order.
        omega: Natural frequency [rad/s] of the critically damped dynamics.
        widths: Time standard deviations of the components [s], ``(K,)``: soft switching,
            ``r_t = sum_k h_k(t) a_k`` with the GMR responsibilities ``h_k(t)`` (eq. 19);
            ``None`` for hard switches at the midpoints between sorted centres.
        priors: Component priors ``pi_k`` ``(K,)`` for the soft switch; ``None`` for equal.

    Attributes:
        order: ``(K,)`` component index of each attractor (attractors are sorted by time).
        blend: ``(T, K)`` share of each attractor in the target during each step.
        free: ``(T + 1, 2)`` response to the initial state ``(x_0, v_0)``.
        psi: ``(T + 1, K)`` response to the attractors, ``Psi``.
    """

    def __init__(
        self,
        n_steps: int,
        dt: float,
        centres: np.ndarray,
        omega: float,
        widths: np.ndarray | None = None,
        priors: np.ndarray | None = None,
    ):
        centres = np.asarray(centres, dtype=float).ravel()
        if n_steps < 1 or not dt > 0 or not omega > 0 or centres.size < 1:
            raise ImitateError(
                f"attractor dynamics need n_steps >= 1, dt > 0, omega > 0 and >= 1 centre; got "
                f"n_steps={n_steps}, dt={dt}, omega={omega}, {centres.size} centres"
            )
        self.n_steps, self.dt, self.omega = int(n_steps), float(dt), float(omega)
        self.order = np.argsort(centres)
        sorted_centres = centres[self.order]
        mid = (np.arange(n_steps) + 0.5) * dt
        K = centres.size
        if widths is None:
            edges = 0.5 * (sorted_centres[1:] + sorted_centres[:-1])
            self.blend = np.eye(K)[np.searchsorted(edges, mid)]
        else:
            sd = np.asarray(widths, dtype=float).ravel()[self.order]
            prior = np.ones(K) if priors is None else np.asarray(priors, float).ravel()[self.order]
            log = np.log(prior) - np.log(sd) - 0.5 * ((mid[:, None] - sorted_centres) / sd) ** 2
            h = np.exp(log - log.max(axis=1, keepdims=True))
            self.blend = h / h.sum(axis=1, keepdims=True)
        A, B = _zero_order_hold(self.omega, self.dt)
        free = np.empty((n_steps + 1, 2, 2))  # state response to s_0 = e_0, e_1
        forced = np.zeros((n_steps + 1, 2, K))
        free[0] = np.eye(2)
        for t in range(n_steps):
            free[t + 1] = A @ free[t]
            forced[t + 1] = A @ forced[t]
            forced[t + 1] += np.outer(B, self.blend[t])
        self.free = free[:, 0, :]
        self.psi = forced[:, 0, :]

    @property
    def n_attractors(self) -> int:
        """Number of attractors ``K``."""
        return self.psi.shape[1]

    def trajectory(self, a: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Task trajectory ``x_{0:T}``, shape ``(T + 1, m)``, from ``x0`` ``(m,)`` at rest.

        Args:
            a: Attractor points, shape ``(K, m)``, sorted by time.
            x0: Start ``(m,)``.
        """
        return self.free[:, :1] * x0 + self.psi @ a

    def gradient(self, dx: np.ndarray) -> np.ndarray:
        """Gradient w.r.t. the attractors ``(K, m)`` from the gradient w.r.t. ``x_{0:T}``."""
        return self.psi.T @ dx

    def fit(
        self,
        target: np.ndarray,
        x0: np.ndarray,
        weights: np.ndarray | None = None,
        reg: float = 1e-6,
    ) -> np.ndarray:
        """Attractors whose trajectory from ``x0`` at rest fits ``target`` in least squares.

        Args:
            target: ``(T + 1, m)``, e.g. the GMR mean.
            x0: Start ``(m,)``.
            weights: ``W_t`` of the residuals: ``(T + 1, m)`` diagonals, e.g. eq. 21's (then the
                fit minimises the similarity cost alone), or ``(T + 1, m, m)`` matrices;
                ``None`` for equal.
            reg: Tikhonov weight, relative to each dimension's mean weight, pulling each
                attractor towards the target's mean over the steps it acts in (keeps an
                attractor that barely acts well defined).

        Returns:
            ``(K, m)`` attractor points.
        """
        K, m = self.n_attractors, target.shape[1]
        share = self.blend / np.maximum(self.blend.sum(axis=0), 1e-12)
        prior = share.T @ target[1:]
        residual = target - self.free[:, :1] * x0
        if weights is None:
            weights = np.ones_like(target)
        if weights.ndim == 3:  # whole matrices: one system over all dimensions
            return self._fit_coupled(residual, prior, weights, reg)
        a = np.empty((K, m))
        for d in range(m):
            w = weights[:, d]
            scale = reg * max(float(w.mean()), 1e-12)
            lhs = self.psi.T @ (w[:, None] * self.psi) + scale * np.eye(K)
            a[:, d] = np.linalg.solve(lhs, self.psi.T @ (w * residual[:, d]) + scale * prior[:, d])
        return a

    def _fit_coupled(
        self, residual: np.ndarray, prior: np.ndarray, weights: np.ndarray, reg: float
    ) -> np.ndarray:
        """:meth:`fit` for ``(T + 1, m, m)`` weights, which couple the dimensions: the normal
        equations of ``sum_t (psi_t a - r_t)^T W_t (psi_t a - r_t)`` over ``vec(a)``."""
        K, m = prior.shape
        lhs = np.einsum("tk,tl,tij->kilj", self.psi, self.psi, weights).reshape(K * m, K * m)
        rhs = np.einsum("tk,tij,tj->ki", self.psi, weights, residual)
        diagonal = np.diagonal(weights, axis1=1, axis2=2)
        scale = reg * np.maximum(diagonal.mean(axis=0), 1e-12)  # (m,)
        lhs += np.diag(np.tile(scale, K))
        rhs += scale * prior
        return np.linalg.solve(lhs, rhs.ravel()).reshape(K, m)
