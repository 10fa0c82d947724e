"""Compiled EM kernels of :mod:`imitate.learning.gmm`: Cholesky factors, log densities, E-step, EM
loop.

Samples are sorted by their first dimension (time) and processed in blocks; per block, the
components whose responsibilities a lower bound of the Mahalanobis distance already puts below
the flush threshold are skipped.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from imitate._numba import ensure_writable
from imitate.learning.kmeans import _EPS_COUNTS, _argsort

ensure_writable(__file__)  # before the kernels below are declared

_LOG_2PI = np.log(2.0 * np.pi)
# Responsibilities below exp(-50) ~ 2e-22 of a sample's largest are flushed to 0: over all N
# samples they add less than N * 2e-22 to a soft count (below round-off for any component that
# holds a hundredth of a sample), and skipping them lets most components go unevaluated.
_LOG_FLUSH = -50.0
_BLOCK = 128  # samples per block: the scratch arrays stay in the L1 cache


@numba.njit(cache=True)
def _factor(
    weights: np.ndarray, covariances: np.ndarray, prec_chol: np.ndarray, log_coef: np.ndarray
) -> bool:
    """Cholesky factors of the precisions and log normalisers of all components, in place.

    Args:
        weights: Priors ``pi_k``, shape ``(K,)``.
        covariances: ``Sigma_k``, shape ``(K, D, D)``, symmetric.
        prec_chol: Output, shape ``(K, D, D)``: ``U_k = L_k^{-T}`` (upper triangle, zeros below)
            with ``Sigma_k = L_k L_k^T``, so that ``Sigma_k^{-1} = U_k U_k^T`` (scikit-learn's
            ``precisions_cholesky_``).
        log_coef: Output, shape ``(K,)``: ``log pi_k - log |L_k| - D/2 log(2 pi)``.

    Returns:
        ``False`` if a covariance is not positive definite (outputs then undefined).
    """
    n_components, d, _ = covariances.shape
    chol = np.zeros((d, d))
    for k in range(n_components):
        log_det = 0.0
        for j in range(d):
            s = covariances[k, j, j]
            for e in range(j):
                s -= chol[j, e] * chol[j, e]
            if not s > 0.0:
                return False
            chol[j, j] = math.sqrt(s)
            log_det += math.log(chol[j, j])
            for r in range(j + 1, d):
                t = covariances[k, r, j]
                for e in range(j):
                    t -= chol[r, e] * chol[j, e]
                chol[r, j] = t / chol[j, j]
        for j in range(d):
            prec_chol[k, j, j] = 1.0 / chol[j, j]
            for r in range(j + 1, d):
                t = 0.0
                for e in range(j, r):
                    t -= chol[r, e] * prec_chol[k, j, e]
                prec_chol[k, j, r] = t / chol[r, r]
        log_coef[k] = math.log(weights[k]) - log_det - 0.5 * d * _LOG_2PI
    return True


@numba.njit(cache=True)
def _block_differences(
    xt: np.ndarray, start: int, stop: int, mean: np.ndarray, diff: np.ndarray
) -> None:
    """``diff[e, i] = xt[e, start + i] - mean[e]`` for one block, ``diff`` of shape ``(D, B)``."""
    for e in range(xt.shape[0]):
        source = xt[e, start:stop]
        target = diff[e]
        mu = mean[e]
        for i in range(stop - start):
            target[i] = source[i] - mu


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def _accumulate_moments(
    resp: np.ndarray, diff: np.ndarray, size: int, k: int, counts: np.ndarray,
    first: np.ndarray, second: np.ndarray,
) -> None:
    """Adds one block's weighted moments to component ``k``: ``counts[k] += sum_i r_i``,
    ``first[k] += sum_i r_i d_i`` and the lower triangle of ``second[k] += sum_i r_i d_i d_i^T``.

    ``resp`` (B,) holds ``r_i``, ``diff`` (D, B) the differences ``d_i``; only the first ``size``
    samples count. The sums are reassociated (vectorised); all terms are finite.
    """
    d = diff.shape[0]
    total = 0.0
    for i in range(size):
        total += resp[i]
    counts[k] += total
    weighted = np.empty(size)
    for e in range(d):
        diff_e = diff[e]
        for i in range(size):
            weighted[i] = resp[i] * diff_e[i]
        total = 0.0
        for i in range(size):
            total += weighted[i]
        first[k, e] += total
        for f in range(e + 1):
            diff_f = diff[f]
            total = 0.0
            for i in range(size):
                total += weighted[i] * diff_f[i]
            second[k, e, f] += total


@numba.njit(cache=True)
def _block_log_densities(
    xt: np.ndarray, start: int, stop: int, means: np.ndarray, prec_chol: np.ndarray,
    log_coef: np.ndarray, threshold: float, terms: np.ndarray, diff: np.ndarray,
    partial: np.ndarray, tops: np.ndarray, kept: np.ndarray, valid: np.ndarray,
) -> None:
    """Weighted log-densities ``log pi_k N(x_i; mu_k, Sigma_k)`` of one block of samples.

    The samples are sorted by their first dimension, so the block spans a short interval of it;
    ``(x_0 - mu_k0)^2 / Sigma_k00``, evaluated at the interval's point nearest ``mu_k0``, is a
    lower bound of every sample's Mahalanobis distance to component ``k``. Components are visited
    from the largest resulting upper bound down; once a component's bound is more than
    ``-threshold`` below the smallest best-so-far term of the block, it and all following ones
    are left out (``-inf``): their responsibilities would be below ``exp(threshold)``. Each
    evaluated component costs ``D (D + 3) / 2`` multiply-adds per sample, in loops over the
    samples (vectorised), or a copy (see ``kept``).

    Args:
        xt: Sorted samples, transposed, shape ``(D, N)``.
        start: First sample of the block.
        stop: One past the block's last sample (the block is ``start..stop-1``).
        means: Component means ``mu_k``, shape ``(K, D)``.
        prec_chol: Cholesky factors ``U_k`` of the precisions, shape ``(K, D, D)``, see
            :func:`_factor`.
        log_coef: Log normalisers ``log pi_k - log |L_k| - D/2 log(2 pi)``, shape ``(K,)``, see
            :func:`_factor`.
        threshold: Log-ratio to a sample's best term below which terms may be dropped (< 0).
        terms: Output, shape ``(K, >= stop - start)``.
        diff: Scratch, shape ``(D, B)`` with ``B >= stop - start``: the samples minus a mean.
        partial: Scratch, shape ``(B,)``: one row of ``U_k^T d_i`` at a time.
        tops: Output, shape ``(B,)``: each sample's largest term.
        kept: Log-densities kept across calls, shape ``(K, N)``, or ``(0, 0)`` to keep nothing:
            a component's row of this block is copied from it where ``valid``, else computed
            and stored in it.
        valid: Which blocks of ``kept`` hold current values, shape ``(K, N / B)`` (rounded up),
            boolean, or ``(0, 0)`` to keep nothing; set here for the rows computed.
    """
    n_components, d = means.shape
    block = start // _BLOCK
    keep = valid.shape[0] > 0
    size = stop - start
    lo, hi = xt[0, start], xt[0, stop - 1]
    bounds = np.empty(n_components)
    negated = np.empty(n_components)
    for k in range(n_components):
        gap = max(lo - means[k, 0], means[k, 0] - hi, 0.0) * prec_chol[k, 0, 0]
        bounds[k] = log_coef[k] - 0.5 * gap * gap
        negated[k] = -bounds[k]
    order = np.empty(n_components, dtype=np.intp)
    _argsort(negated, order)
    tops[:size] = -np.inf
    floor = -np.inf  # smallest best-so-far term over the block
    for rank in range(n_components):
        k = order[rank]
        if bounds[k] - floor < threshold:
            for rest in range(rank, n_components):
                terms[order[rest], :size] = -np.inf
            return
        row = terms[k]
        if keep and valid[k, block]:
            for i in range(size):
                row[i] = kept[k, start + i]
        else:
            _block_differences(xt, start, stop, means[k], diff)
            for i in range(size):
                row[i] = log_coef[k]
            for j in range(d):  # partial = (U_k^T d_i)_j, one pass per term, the first storing
                u = prec_chol[k, 0, j]
                diff_e = diff[0]
                for i in range(size):
                    partial[i] = 0.0 + u * diff_e[i]
                for e in range(1, j + 1):
                    u = prec_chol[k, e, j]
                    diff_e = diff[e]
                    for i in range(size):
                        partial[i] += u * diff_e[i]
                for i in range(size):
                    row[i] -= 0.5 * partial[i] * partial[i]
            if keep:
                for i in range(size):
                    kept[k, start + i] = row[i]
                valid[k, block] = True
        floor = np.inf
        for i in range(size):
            tops[i] = max(tops[i], row[i])
            floor = min(floor, tops[i])


@numba.njit(cache=True)
def _block_log_norm(
    terms: np.ndarray, tops: np.ndarray, size: int, threshold: float, sums: np.ndarray
) -> None:
    """``tops[i] = log sum_k exp(terms[k, i])`` for one block, by the log-sum-exp trick.

    ``tops`` holds each sample's largest term on entry (as :func:`_block_log_densities` leaves
    it); terms below ``exp(threshold)`` of it are dropped. Loops over the samples, for every
    sample the terms in the order of ``k``. ``sums`` is scratch, shape ``(B,)``.
    """
    for i in range(size):
        sums[i] = 0.0
    for k in range(terms.shape[0]):
        row = terms[k]
        for i in range(size):
            if row[i] - tops[i] >= threshold:
                sums[i] += math.exp(row[i] - tops[i])
    for i in range(size):
        tops[i] += math.log(sums[i])


@numba.njit(cache=True)
def _e_step(
    xt: np.ndarray, means: np.ndarray, prec_chol: np.ndarray, log_coef: np.ndarray,
    threshold: float, resp: np.ndarray, kept: np.ndarray, valid: np.ndarray,
) -> np.ndarray:
    """Per-sample log-likelihood ``log p(x_i)`` (eq. 3), shape ``(N,)``, of sorted samples.

    Args:
        xt: Samples sorted by their first dimension, transposed, shape ``(D, N)``.
        means: Component means ``mu_k``, shape ``(K, D)``.
        prec_chol: Cholesky factors ``U_k`` of the precisions, shape ``(K, D, D)``, see
            :func:`_factor`.
        log_coef: Log normalisers, shape ``(K,)``, see :func:`_factor`.
        threshold: Terms below ``exp(threshold)`` of a sample's largest are dropped (< 0).
        resp: Output, shape ``(N, K)``, or ``(0, K)`` to skip it: responsibilities ``p(k | x_i)``
            (eq. 8), exactly 0 where below ``exp(threshold)``.
        kept: Log-densities kept across calls, shape ``(K, N)`` or ``(0, 0)``, see
            :func:`_block_log_densities`.
        valid: Which blocks of ``kept`` are current, shape ``(K, ceil(N / B))`` or ``(0, 0)``,
            see :func:`_block_log_densities`.
    """
    d, n = xt.shape
    n_components = means.shape[0]
    terms = np.empty((n_components, _BLOCK))
    diff = np.empty((d, _BLOCK))
    partial = np.empty(_BLOCK)
    tops = np.empty(_BLOCK)
    log_norm = np.empty(n)
    for start in range(0, n, _BLOCK):
        stop = min(start + _BLOCK, n)
        _block_log_densities(xt, start, stop, means, prec_chol, log_coef, threshold, terms,
                             diff, partial, tops, kept, valid)
        _block_log_norm(terms, tops, stop - start, threshold, partial)
        for i in range(stop - start):
            log_norm[start + i] = tops[i]
            if resp.shape[0] == n:
                for k in range(n_components):
                    log_resp = terms[k, i] - log_norm[start + i]
                    resp[start + i, k] = math.exp(log_resp) if log_resp >= threshold else 0.0
    return log_norm


@numba.njit(cache=True)
def _em_loop(
    xt: np.ndarray, weights: np.ndarray, means: np.ndarray, covariances: np.ndarray,
    reg_covar: float, tol: float, max_iter: int,
) -> tuple[int, bool, float, bool]:
    """EM (eqs. 8-12) in place on ``weights`` (K,), ``means`` (K, D), ``covariances`` (K, D, D).

    Each iteration is one pass over the blocks of sorted samples ``xt`` (D, N): the E-step of a
    block (responsibilities below ``exp(-50)`` flushed to 0) is accumulated at once into the
    soft counts and the first and second moments about the current means; the M-step then
    shifts the means and subtracts the shift from the second moments. Stops when the mean
    log-likelihood per sample (before the M-step) changes by less than ``tol``.

    Returns:
        ``(n_iter, converged, lower_bound, positive_definite)``; ``positive_definite`` is
        ``False`` when a covariance lost definiteness (parameters then undefined).
    """
    d, n = xt.shape
    n_components = means.shape[0]
    prec_chol = np.zeros((n_components, d, d))
    log_coef = np.empty(n_components)
    if not _factor(weights, covariances, prec_chol, log_coef):
        return 0, False, -np.inf, False
    counts = np.empty(n_components)
    first = np.empty((n_components, d))
    second = np.empty((n_components, d, d))
    terms = np.empty((n_components, _BLOCK))
    diff = np.empty((d, _BLOCK))
    partial = np.empty(_BLOCK)
    tops = np.empty(_BLOCK)
    resp = np.empty(_BLOCK)
    nothing, nothing_valid = np.empty((0, 0)), np.empty((0, 0), dtype=np.bool_)  # keeps none
    lower_bound = -np.inf
    n_iter = 0
    while n_iter < max_iter:
        n_iter += 1
        previous = lower_bound
        counts[:] = 0.0
        first[:] = 0.0
        second[:] = 0.0
        total = 0.0
        for start in range(0, n, _BLOCK):
            stop = min(start + _BLOCK, n)
            _block_log_densities(xt, start, stop, means, prec_chol, log_coef, _LOG_FLUSH,
                                 terms, diff, partial, tops, nothing, nothing_valid)
            size = stop - start
            _block_log_norm(terms, tops, size, _LOG_FLUSH, partial)  # log p(x_i), in tops
            for i in range(size):
                total += tops[i]
            for k in range(n_components):
                row = terms[k]
                used = False
                for i in range(size):
                    log_resp = row[i] - tops[i]
                    resp[i] = math.exp(log_resp) if log_resp >= _LOG_FLUSH else 0.0
                    used = used or resp[i] > 0.0
                if used:
                    _block_differences(xt, start, stop, means[k], diff)
                    _accumulate_moments(resp, diff, size, k, counts, first, second)
        total_counts = 0.0
        for k in range(n_components):
            counts[k] += _EPS_COUNTS  # e_k, eq. 9
            total_counts += counts[k]
        for k in range(n_components):
            weights[k] = counts[k] / total_counts  # eq. 10
            for e in range(d):
                first[k, e] /= counts[k]
            for e in range(d):
                for f in range(e + 1):  # eq. 12 about the new mean (eq. 11)
                    c = second[k, e, f] / counts[k] - first[k, e] * first[k, f]
                    covariances[k, e, f] = c
                    covariances[k, f, e] = c
                covariances[k, e, e] += reg_covar
                means[k, e] += first[k, e]
        lower_bound = total / n
        if not _factor(weights, covariances, prec_chol, log_coef):
            return n_iter, False, lower_bound, False
        if abs(lower_bound - previous) < tol:
            return n_iter, True, lower_bound, True
    return n_iter, False, lower_bound, True


def _sorted_transposed(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples sorted by their first dimension and transposed, ``(D, N)``, and the order."""
    order = np.argsort(X[:, 0], kind="stable")
    return np.ascontiguousarray(X[order].T), order


@numba.njit(cache=True)
def _cluster_parameters(
    x: np.ndarray, labels: np.ndarray, n_components: int, reg_covar: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The M-step (eqs. 9-12) for hard responsibilities: counts and means in one pass over the
    samples, covariances about those means in a second (no cancellation)."""
    n, d = x.shape
    counts = np.zeros(n_components)
    means = np.zeros((n_components, d))
    cov = np.zeros((n_components, d, d))
    for i in range(n):
        c = labels[i]
        counts[c] += 1.0
        for e in range(d):
            means[c, e] += x[i, e]
    for c in range(n_components):  # element loops: no compiled shape checks (see _copy_row)
        counts[c] += _EPS_COUNTS
        for e in range(d):
            means[c, e] /= counts[c]
    diff = np.empty(d)
    for i in range(n):
        c = labels[i]
        for e in range(d):
            diff[e] = x[i, e] - means[c, e]
        for e in range(d):
            for f in range(e + 1):
                cov[c, e, f] += diff[e] * diff[f]
    for c in range(n_components):
        for e in range(d):
            for f in range(e + 1):
                cov[c, e, f] /= counts[c]
                cov[c, f, e] = cov[c, e, f]
            cov[c, e, e] += reg_covar
    total = 0.0
    for c in range(n_components):
        total += counts[c]
    weights = np.empty(n_components)
    for c in range(n_components):
        weights[c] = counts[c] / total
    return weights, means, cov
