"""K-means: against scikit-learn, Hamerly's bounds against plain Lloyd."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.cluster import KMeans

from imitate.learning.kmeans import _assign_all, _lloyd, kmeans


def test_kmeans_matches_sklearn_on_blobs():
    rng = np.random.default_rng(3)
    X = np.vstack([c + rng.normal(scale=0.2, size=(100, 3)) for c in rng.normal(0, 5, (5, 3))])
    ours = kmeans(X, 5)
    ref = KMeans(5, n_init=3, random_state=0).fit(X)
    np.testing.assert_allclose(ours.inertia, ref.inertia_, rtol=1e-9)
    assert len(set(zip(ours.labels.tolist(), ref.labels_.tolist(), strict=True))) == 5


@pytest.mark.parametrize("k", [2, 7, 20])
def test_lloyd_with_bounds_converges_like_plain_lloyd(demo_data, k):
    # Hamerly's bounds only skip distance computations: from the same centres the converged
    # clustering is scikit-learn's plain Lloyd result.
    x = demo_data - demo_data.mean(axis=0)  # as scikit-learn centres it
    init = x[np.random.default_rng(k).choice(len(x), k, replace=False)]
    centres = init.copy()
    labels, upper, lower = np.empty(len(x), dtype=np.intp), np.empty(len(x)), np.empty(len(x))
    _assign_all(x, centres, labels, upper, lower)
    inertia, _ = _lloyd(x, centres, labels, upper, lower, 1000, 0.0)
    ref = KMeans(k, init=init, n_init=1, max_iter=1000, tol=0.0, algorithm="lloyd").fit(x)
    np.testing.assert_array_equal(labels, ref.labels_)
    np.testing.assert_allclose(inertia, ref.inertia_, rtol=1e-9)
    np.testing.assert_allclose(centres, ref.cluster_centers_, rtol=1e-9, atol=1e-12)

