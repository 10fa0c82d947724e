r"""Gaussian mixture regression (paper eqs. 13-19), vectorised over all query times.

Each component's mean and covariance are split into an input part (time, subscript ``t``) and an
output part (task space, subscript ``s``). For every query input ``x_t`` the components are
conditioned (eqs. 15-16), weighted by ``beta_k`` (eq. 19, computed in log space) and mixed
(eq. 17). The mixture's covariance has two variants:

- ``"paper"``: eq. 18, :math:`\hat\Sigma_s = \sum_k \beta_k^2 \hat\Sigma_{s,k}`, as the paper
  writes it (it treats the components as independent estimates, so it shrinks where components
  overlap);
- ``"total"``: the law of total covariance, :math:`\sum_k \beta_k (\hat\Sigma_{s,k} +
  \hat x_{s,k} \hat x_{s,k}^T) - \hat x_s \hat x_s^T`, the exact covariance of the conditional
  mixture (equal to gmr's ``GMM.condition(...).to_mvn()``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError
from imitate.learning.gmm import GMM, exp_flushed

__all__ = ["gmr"]

_LOG_2PI = np.log(2.0 * np.pi)
_COVARIANCES = ("paper", "total")


def gmr(
    gmm: GMM,
    t: ArrayLike,
    in_dims: Sequence[int] = (0,),
    covariance: str = "paper",
) -> tuple[np.ndarray, np.ndarray]:
    """Conditional mean and covariance of the outputs given the inputs at every query.

    Args:
        gmm: A fitted :class:`~imitate.learning.gmm.GMM` over ``D`` dimensions (``weights_``,
            ``means_``, ``covariances_``).
        t: Query inputs, shape ``(T,)`` for one input dimension or ``(T, len(in_dims))``, in the
            units of the input dimensions (time [s] for the paper).
        in_dims: Indices of the input dimensions, distinct, in ``[0, D)``, not all of them.
        covariance: ``"paper"`` (eq. 18) or ``"total"`` (law of total covariance).

    Returns:
        ``(mean, cov)``: ``mean`` of shape ``(T, D - len(in_dims))`` (eq. 17) and ``cov`` of shape
        ``(T, D - len(in_dims), D - len(in_dims))``; outputs in increasing dimension order.

    Raises:
        ImitateError: On an unfitted model, bad ``in_dims``, ``t`` of the wrong shape or
            non-finite, or an unknown ``covariance``.
    """
    if covariance not in _COVARIANCES:
        raise ImitateError(f"covariance must be one of {_COVARIANCES}; got {covariance!r}")
    if not hasattr(gmm, "means_"):
        raise ImitateError("the GMM is not fitted; call fit(X) or GMM.from_parameters first")
    weights, means, covs = gmm.weights_, gmm.means_, gmm.covariances_
    n_dims = means.shape[1]
    inp = np.asarray(in_dims, dtype=int).ravel()
    if (
        inp.size == 0
        or inp.size >= n_dims
        or np.unique(inp).size != inp.size
        or np.any((inp < 0) | (inp >= n_dims))
    ):
        raise ImitateError(
            f"in_dims must be distinct indices in [0, {n_dims - 1}] leaving at least one output; "
            f"got {tuple(np.asarray(in_dims).ravel().tolist())}"
        )
    out = np.setdiff1d(np.arange(n_dims), inp)
    q = np.asarray(t, dtype=float)
    if q.ndim == 1 and inp.size == 1:
        q = q[:, None]
    if q.ndim != 2 or q.shape[1] != inp.size or q.shape[0] == 0:
        raise ImitateError(
            f"t must have shape (T,) or (T, {inp.size}) for {inp.size} input dimension(s); "
            f"got {np.shape(t)}"
        )
    if not np.all(np.isfinite(q)):
        raise ImitateError("t must be finite")

    mu_in, mu_out = means[:, inp], means[:, out]  # eq. 13
    s_ii = covs[:, inp[:, None], inp]  # eq. 14
    s_oi = covs[:, out[:, None], inp]
    s_oo = covs[:, out[:, None], out]
    chol = np.linalg.cholesky(s_ii)
    chol_inv = np.linalg.inv(chol)  # (K, Di, Di)
    # Regression coefficients sigma_st sigma_tt^{-1} = (S_oi L^{-T}) L^{-1}.
    half = s_oi @ chol_inv.transpose(0, 2, 1)  # (K, Do, Di)
    coef = half @ chol_inv
    cond_cov = s_oo - half @ half.transpose(0, 2, 1)  # eq. 16, (K, Do, Do)

    diff = q[:, None, :] - mu_in[None, :, :]  # (T, K, Di)
    cond_mean = mu_out[None] + np.einsum("koi,tki->tko", coef, diff)  # eq. 15, (T, K, Do)
    y = np.einsum("kij,tkj->tki", chol_inv, diff)
    log_beta = np.log(weights) - np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
    log_beta = log_beta - 0.5 * (inp.size * _LOG_2PI + np.einsum("tki,tki->tk", y, y))
    log_beta -= log_beta.max(axis=1, keepdims=True)
    beta = exp_flushed(log_beta)
    beta /= beta.sum(axis=1, keepdims=True)  # eq. 19, (T, K)

    mean = np.einsum("tk,tko->to", beta, cond_mean)  # eq. 17
    n_out = out.size
    flat_cov = cond_cov.reshape(cond_cov.shape[0], n_out * n_out)
    if covariance == "paper":
        cov = (beta**2 @ flat_cov).reshape(-1, n_out, n_out)  # eq. 18
    else:
        spread = cond_mean - mean[:, None, :]
        cov = (beta @ flat_cov).reshape(-1, n_out, n_out)
        cov += np.einsum("tk,tki,tkj->tij", beta, spread, spread)
    return mean, cov
