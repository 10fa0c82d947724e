"""Checks of the samples given to K-means, the GMM and the BIC sweep (shared by those modules)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError


def check_samples(
    X: ArrayLike, name: str = "X", row: str = "sample", shape: str = "(n_samples, n_dims)",
    hint: str = "",
) -> np.ndarray:
    """Validates samples as a finite float array of shape ``(n_samples, n_dims)``.

    Args:
        X: The samples.
        name: How the messages call them.
        row: How they call one row (``"sample"``, ``"step"``).
        shape: How they write the shape asked for.
        hint: What the message about a non-finite value adds (``"; interpolate ..."``).

    Returns:
        The samples as a C-contiguous float array (``X`` itself when it already is one).
    """
    arr = np.ascontiguousarray(X, dtype=float)
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ImitateError(
            f"{name} must be a non-empty array of shape {shape}; got shape {np.shape(X)}"
        )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ImitateError(
            f"{name} contains a non-finite value ({arr[tuple(bad)]}) at {row} {bad[0]}, "
            f"dimension {bad[1]}{hint}"
        )
    return arr


def check_n_components(n_components: int, n_samples: int) -> None:
    """Validates a number of components (or clusters): an integer in ``[1, n_samples]``."""
    if not isinstance(n_components, (int, np.integer)) or n_components < 1:
        raise ImitateError(f"the number of components must be an integer >= 1; got {n_components}")
    if n_components > n_samples:
        raise ImitateError(
            f"more components ({n_components}) than samples ({n_samples}); use at most "
            f"{n_samples} components or provide more data"
        )
