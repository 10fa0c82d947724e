"""The learning stage (paper section IV and V-A): demonstrations -> GMR mean and variance over time.

Task-space demonstrations are aligned by DTW onto the medoid (:mod:`imitate.learning.dtw`), time is
prepended as the first dimension, the number of components is chosen by BIC
(:func:`imitate.learning.bic.bic_sweep`), a GMM is trained by EM from the sweep's K-means start of
that
``K`` (:class:`imitate.learning.gmm.GMM`; the clustering is not repeated) and conditioned on time
by GMR (:func:`imitate.learning.gmr.gmr`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError
from imitate.learning.bic import DEFAULT_BIC, bic_sweep
from imitate.learning.dtw import Alignment, align
from imitate.learning.gmm import GMM
from imitate.learning.gmr import gmr

__all__ = ["LearnedModel", "LearningConfig", "learn", "time_stacked"]


@dataclass(frozen=True)
class LearningConfig:
    """Parameters of :func:`learn`.

    Attributes:
        n_components: Fixed number of GMM components; ``None`` chooses it by BIC.
        k_max: Largest number of components tried by the BIC sweep.
        bic_method: ``"full"`` (EM for every K, the default) or ``"fast"`` (the paper's K-means
            heuristic), see :data:`imitate.learning.bic.BIC_METHODS`.
        use_dtw: Align the demonstrations by DTW (``False`` reproduces Fig. 4, left: each
            demonstration keeps its own time axis).
        dtw_weights: Per-dimension DTW scale factors, shape ``(n_dims,)``; ``None`` for the
            inverse pooled standard deviation.
        covariance: GMR covariance, ``"paper"`` (eq. 18) or ``"total"``.
        reg_covar: Covariance regularisation of the GMM (squared data units).
        tol: EM tolerance on the mean log-likelihood per sample [nats].
        max_iter: EM iteration limit.
        n_init: Number of k-means++ starts.
        seed: Seed of the K-means starts.
    """

    n_components: int | None = None
    k_max: int = 30
    bic_method: str = DEFAULT_BIC
    use_dtw: bool = True
    dtw_weights: tuple[float, ...] | None = None
    covariance: str = "paper"
    reg_covar: float = 1e-6
    tol: float = 1e-3
    max_iter: int = 100
    n_init: int = 3
    seed: int = 0


# Slack of the movement's span for predict's warning [s]: rounding at its ends is not outside.
_SPAN_SLACK = 1e-9


@dataclass(frozen=True, repr=False)
class LearnedModel:
    """Output of :func:`learn`.

    Attributes:
        data: GMM training data, shape ``(n_samples, 1 + n_dims)``: time [s], then task space.
        gmm: The fitted GMM over ``(t, x)``.
        bic_curve: BIC for ``K = 1..k_max``, shape ``(k_max,)``; empty if ``K`` was fixed.
        times: GMR query times, shape ``(T,)`` [s].
        mean: GMR mean ``mu_hat_t``, shape ``(T, n_dims)``.
        covariance: GMR covariance, shape ``(T, n_dims, n_dims)``.
        alignment: The DTW alignment, or ``None`` without DTW.
    """

    data: np.ndarray
    gmm: GMM
    bic_curve: np.ndarray
    times: np.ndarray
    mean: np.ndarray
    covariance: np.ndarray
    alignment: Alignment | None

    def predict(self, t: ArrayLike, covariance: str = "paper") -> tuple[np.ndarray, np.ndarray]:
        """GMR at times ``t`` [s], scalar or ``(T,)``, of the fitted GMM (not limited to
        :attr:`times`). Times outside the movement's span (:attr:`times`' first to last) give
        the GMM's extrapolation, which the demonstrations never showed: a ``UserWarning`` says
        so (``warnings.simplefilter("ignore", UserWarning)`` silences it).

        Args:
            t: Query times [s], finite.
            covariance: ``"paper"`` (eq. 18, as :func:`learn` computes :attr:`covariance` by
                default) or ``"total"``, see :func:`imitate.learning.gmr.gmr`.

        Returns:
            ``(mean, covariance)``: ``mu_hat_t`` of shape ``(T, n_dims)`` and ``(T, n_dims,
            n_dims)``; a scalar ``t`` gives ``T = 1``.

        Raises:
            ImitateError: ``t`` not finite or of another shape, or an unknown ``covariance``.
        """
        try:
            times = np.atleast_1d(np.asarray(t, dtype=float))
        except (TypeError, ValueError):
            raise ImitateError(
                f"t must be times [s], a number or (T,) numbers; got {t!r}"
            ) from None
        start, end = float(self.times[0]), float(self.times[-1])
        outside = (times < start - _SPAN_SLACK) | (times > end + _SPAN_SLACK)
        if outside.any():
            warnings.warn(
                f"predict at t = {times[outside][0]:g} s, outside the movement's {start:g}.."
                f"{end:.3g} s: the GMM extrapolates there (the demonstrations never went there)",
                UserWarning, stacklevel=2,
            )
        return gmr(self.gmm, times, covariance=covariance)

    def __repr__(self) -> str:
        return (
            f"LearnedModel({len(self.gmm.weights_)} components, {self.mean.shape[1]} task dims, "
            f"{self.times[0]:g}..{self.times[-1]:.3g} s in {len(self.times)} steps, data "
            f"{self.data.shape}, mean {self.mean.shape}, covariance {self.covariance.shape})"
        )

    @property
    def variance(self) -> np.ndarray:
        """GMR variances ``sigma_hat_t`` (the covariance diagonals), shape ``(T, n_dims)``."""
        return np.diagonal(self.covariance, axis1=1, axis2=2).copy()

    @staticmethod
    def array_names(prefix: str = "") -> tuple[str, ...]:
        """Names of the arrays :meth:`to_arrays` writes (the alignment is not stored)."""
        return tuple(prefix + name for name in _ARRAYS)

    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The model as named arrays (for ``model.npz``), each name prefixed by ``prefix``: the
        fields, and the GMM's ``weights`` ``(K,)``, ``means`` ``(K, 1 + n_dims)`` and
        ``covariances`` ``(K, 1 + n_dims, 1 + n_dims)``."""
        g = self.gmm
        arrays = {
            "data": self.data, "weights": g.weights_, "means": g.means_,
            "covariances": g.covariances_, "bic_curve": self.bic_curve, "times": self.times,
            "mean": self.mean, "covariance": self.covariance,
        }
        return {prefix + name: arrays[name] for name in _ARRAYS}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> LearnedModel:
        """The model stored by :meth:`to_arrays` under ``prefix``, without its alignment.

        Raises:
            ImitateError: an array holds NaN or inf, the GMR's arrays disagree in shape, or
                the GMM's parameters are inconsistent.
        """
        a = {name: arrays[prefix + name] for name in _ARRAYS}
        bad = [prefix + n for n, v in a.items()  # (bic_curve: drawn only, may hold inf)
               if n != "bic_curve" and not np.isfinite(np.asarray(v, float)).all()]
        if bad:
            raise ImitateError(f"{', '.join(bad)} must be finite (no NaN or inf)")
        _check_shapes(a)
        gmm = GMM.from_parameters(a.pop("weights"), a.pop("means"), a.pop("covariances"))
        return cls(gmm=gmm, alignment=None, **a)


_ARRAYS = ("data", "weights", "means", "covariances", "bic_curve", "times", "mean", "covariance")


def _check_shapes(a: Mapping[str, np.ndarray]) -> None:
    """Raise ``ImitateError`` unless the GMR's arrays agree: ``times`` ``(T,)``, ``mean``
    ``(T, d)``, ``covariance`` ``(T, d, d)`` and ``data`` ``(n, 1 + d)``."""
    times, mean = np.shape(a["times"]), np.shape(a["mean"])
    cov, data = np.shape(a["covariance"]), np.shape(a["data"])
    if len(times) != 1 or len(mean) != 2 or mean[0] != times[0] or cov != (*mean, mean[1]) or (
        len(data) != 2 or data[1] != 1 + mean[1]
    ):
        raise ImitateError(
            f"times (T,), mean (T, d), covariance (T, d, d) and data (n, 1 + d) must agree; "
            f"got {times}, {mean}, {cov} and {data}"
        )


def time_stacked(demos: Sequence[np.ndarray], rate: float) -> np.ndarray:
    """Stacks demonstrations into GMM samples ``(t, x)`` with ``t = step / rate``.

    Args:
        demos: Demonstrations, each of shape ``(n_steps_i, n_dims)``.
        rate: Sampling rate [Hz].

    Returns:
        Samples, shape ``(sum_i n_steps_i, 1 + n_dims)``.
    """
    return np.concatenate(
        [np.column_stack((np.arange(len(d)) / rate, d)) for d in demos], axis=0
    )


def learn(
    demos: Sequence[np.ndarray | Sequence[Sequence[float]]],
    *,
    rate: float,
    config: LearningConfig | None = None,
) -> LearnedModel:
    """Learns the GMR mean and covariance over time from segmented demonstrations.

    Args:
        demos: At least 2 task-space demonstrations, each of shape ``(n_steps_i, n_dims)``,
            finite, each at least as long as the number of components (``n_components`` or
            ``k_max``).
        rate: Sampling rate of the demonstrations [Hz].
        config: Parameters; ``None`` for the defaults.

    Returns:
        The :class:`LearnedModel`; GMR is evaluated at the reference demonstration's steps (with
        DTW) or at the steps of the longest demonstration (without).

    Raises:
        ImitateError: Fewer than 2 demonstrations, non-finite samples, mismatched dimensions,
            a demonstration shorter than the number of components, or bad parameters.
    """
    c = config or LearningConfig()
    if not rate > 0:
        raise ImitateError(f"rate must be > 0 [Hz]; got {rate}")
    if len(demos) < 2:
        raise ImitateError(f"learning needs at least 2 demonstrations; got {len(demos)}")
    k_needed = c.n_components if c.n_components is not None else c.k_max
    for n, d in enumerate(demos):
        if len(d) < k_needed:
            raise ImitateError(
                f"demos[{n}] has {len(d)} samples, fewer than the {k_needed} components "
                "asked for; lower n_components / k_max or record longer demonstrations"
            )
    alignment = None
    if c.use_dtw:
        alignment = align(demos, weights=c.dtw_weights)
        series = list(alignment.aligned)
    else:
        series = [np.asarray(d, dtype=float) for d in demos]
        if any(s.ndim != 2 or s.shape[1] != series[0].shape[1] for s in series):
            raise ImitateError(
                "all demonstrations must have shape (n_steps_i, n_dims) with the same n_dims; "
                f"got {[s.shape for s in series]}"
            )
    data = time_stacked(series, rate)
    if c.n_components is None:
        sweep = bic_sweep(
            data, c.k_max, c.bic_method, c.seed, reg_covar=c.reg_covar, n_init=c.n_init,
            tol=c.tol, max_iter=c.max_iter,
        )
        k, curve, init = sweep.k, sweep.curve, sweep.initial_parameters(data, c.reg_covar)
    else:
        k, curve, init = c.n_components, np.empty(0), None
    gmm = GMM(
        k, reg_covar=c.reg_covar, tol=c.tol, max_iter=c.max_iter, n_init=c.n_init, seed=c.seed
    )
    gmm = gmm.fit(data) if init is None else gmm.fit_from(data, *init)
    times = np.arange(max(len(s) for s in series)) / rate
    mean, cov = gmr(gmm, times, covariance=c.covariance)
    return LearnedModel(
        data=data, gmm=gmm, bic_curve=curve, times=times, mean=mean, covariance=cov,
        alignment=alignment,
    )
