"""DTW (eq. 2): cross-check against dtw-python, properties, alignment, bad input."""

from __future__ import annotations

import dtw as dtw_python
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from imitate.errors import ImitateError
from imitate.learning.dtw import align, default_weights, dtw, local_costs, warp_to_reference


def _reference(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    result = dtw_python.dtw(
        a, b, dist_method="euclidean", step_pattern=dtw_python.symmetric1
    )
    return result.distance, np.column_stack((result.index1, result.index2))


@pytest.mark.parametrize("seed", range(12))
def test_matches_dtw_python_on_random_multidimensional_series(seed):
    rng = np.random.default_rng(seed)
    n, m = rng.integers(1, 120, size=2)
    n_dims = int(rng.integers(1, 9))
    a = rng.normal(size=(n, n_dims)) * rng.uniform(0.1, 10.0, size=n_dims)
    b = rng.normal(size=(m, n_dims)) * rng.uniform(0.1, 10.0, size=n_dims) + 1.0
    distance, path = dtw(a, b)
    ref_distance, ref_path = _reference(a, b)
    np.testing.assert_allclose(distance, ref_distance, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(path, ref_path)


@pytest.mark.parametrize("seed", range(8))
def test_ties_are_broken_like_dtw_python(seed):
    # Few distinct integer values: many cells have equal candidates, so the path depends on the
    # tie-breaking order (diagonal, then left, then up).
    rng = np.random.default_rng(100 + seed)
    a = rng.integers(0, 3, size=(int(rng.integers(5, 60)), 2)).astype(float)
    b = rng.integers(0, 3, size=(int(rng.integers(5, 60)), 2)).astype(float)
    distance, path = dtw(a, b)
    ref_distance, ref_path = _reference(a, b)
    assert distance == ref_distance
    np.testing.assert_array_equal(path, ref_path)


def test_matches_dtw_python_at_paper_scale():
    rng = np.random.default_rng(7)
    a = np.cumsum(rng.normal(size=(450, 7)), axis=0)
    b = np.cumsum(rng.normal(size=(430, 7)), axis=0)
    distance, path = dtw(a, b)
    ref_distance, ref_path = _reference(a, b)
    np.testing.assert_allclose(distance, ref_distance, rtol=1e-9)
    np.testing.assert_array_equal(path, ref_path)


def test_weights_scale_each_dimension():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(30, 4)), rng.normal(size=(25, 4))
    w = np.array([1.0, 0.5, 3.0, 0.0])
    distance, path = dtw(a, b, weights=w)
    ref_distance, ref_path = _reference(a * w, b * w)
    np.testing.assert_allclose(distance, ref_distance, rtol=1e-9)
    np.testing.assert_array_equal(path, ref_path)


def test_local_costs_are_exact_near_zero_and_far():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(40, 3)) + 1e3  # large offset: the Gram formula alone would cancel
    b = np.vstack([a[:10] + 1e-9, rng.normal(size=(5, 3)) + 1e3])
    v = local_costs(a, b)
    direct = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)
    np.testing.assert_allclose(v, direct, rtol=1e-9, atol=1e-12)


def test_paper_example_in_docstring():
    distance, path = dtw([0.0, 1.0, 2.0], [0.0, 0.0, 1.0, 2.0])
    assert distance == 0.0
    assert path.tolist() == [[0, 0], [0, 1], [1, 2], [2, 3]]


series = st.integers(1, 25).flatmap(
    lambda n: arrays(np.float64, (n, 2), elements=st.floats(-10, 10, width=64))
)


@settings(max_examples=60, deadline=None)
@given(a=series, b=series)
def test_properties_symmetry_monotone_path_fixed_ends(a, b):
    d_ab, path = dtw(a, b)
    d_ba, _ = dtw(b, a)
    assert d_ab >= 0.0
    np.testing.assert_allclose(d_ab, d_ba, rtol=1e-9, atol=1e-9)
    assert path[0].tolist() == [0, 0]
    assert path[-1].tolist() == [len(a) - 1, len(b) - 1]
    steps = np.diff(path, axis=0)
    assert set(map(tuple, steps.tolist())) <= {(1, 1), (0, 1), (1, 0)}
    v = local_costs(a, b)
    np.testing.assert_allclose(v[path[:, 0], path[:, 1]].sum(), d_ab, rtol=1e-9, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(a=series)
def test_property_self_distance_is_zero_on_the_diagonal(a):
    distance, path = dtw(a, a)
    assert distance == 0.0
    # A zero-cost path exists; where consecutive samples repeat, ties may leave the diagonal.
    v = local_costs(a, a)
    assert v[path[:, 0], path[:, 1]].sum() == 0.0


def _warped_copies(rng: np.random.Generator, n_demos: int) -> list[np.ndarray]:
    """Smooth 3-D signal under monotone time warps of different lengths."""
    demos = []
    for _ in range(n_demos):
        n = int(rng.integers(80, 120))
        u = np.linspace(0.0, 1.0, n)
        s = u + rng.uniform(-0.12, 0.12) * np.sin(np.pi * u)  # monotone warp, fixed ends
        demos.append(np.column_stack([np.sin(2 * np.pi * s), np.cos(3 * s), s**2]))
    return demos


def test_align_matches_pairwise_dtw_and_shares_reference_length():
    rng = np.random.default_rng(0)
    demos = _warped_copies(rng, 4)
    result = align(demos)
    w = default_weights(demos)
    n_ref = len(demos[result.reference])
    assert result.aligned.shape == (4, n_ref, 3)
    np.testing.assert_array_equal(result.aligned[result.reference], demos[result.reference])
    for p in range(4):
        for q in range(4):
            expected = 0.0 if p == q else dtw(demos[p], demos[q], weights=w)[0]
            np.testing.assert_allclose(result.distances[p, q], expected, rtol=1e-9, atol=1e-12)
    assert result.reference == int(np.argmin(result.distances.sum(axis=1)))
    for p, path in enumerate(result.paths):
        assert path[0].tolist() == [0, 0]
        assert path[-1].tolist() == [len(demos[p]) - 1, n_ref - 1]


def test_align_removes_time_warps():
    rng = np.random.default_rng(1)
    demos = _warped_copies(rng, 5)
    result = align(demos)
    raw_spread = np.mean(
        [np.abs(np.interp(np.linspace(0, 1, 100), np.linspace(0, 1, len(d)), d[:, 0])
                - np.interp(np.linspace(0, 1, 100), np.linspace(0, 1, len(demos[0])),
                            demos[0][:, 0])).mean() for d in demos]
    )
    aligned_spread = np.abs(result.aligned[:, :, 0] - result.aligned[result.reference, :, 0])
    assert aligned_spread.mean() < 0.2 * raw_spread


def test_align_with_given_reference_and_weights():
    rng = np.random.default_rng(2)
    demos = _warped_copies(rng, 3)
    result = align(demos, reference=2, weights=[1.0, 1.0, 0.0])
    assert result.reference == 2
    _, path = dtw(demos[0], demos[2], weights=[1.0, 1.0, 0.0])
    np.testing.assert_array_equal(result.paths[0], path)
    np.testing.assert_allclose(
        result.aligned[0], warp_to_reference(demos[0], path, len(demos[2]))
    )


def test_warp_averages_samples_matched_to_one_reference_step():
    demo = np.array([[0.0], [2.0], [4.0]])
    path = np.array([[0, 0], [1, 0], [2, 1]])
    np.testing.assert_allclose(warp_to_reference(demo, path, 2), [[1.0], [4.0]])


def test_default_weights_ignore_constant_dimensions():
    demos = [np.array([[0.0, 1.0], [2.0, 1.0]]), np.array([[0.0, 1.0], [2.0, 1.0]])]
    np.testing.assert_allclose(default_weights(demos), [1.0, 0.0])


@pytest.mark.parametrize(
    ("a", "b", "kwargs", "match"),
    [
        (np.array([[0.0, np.nan]]), np.zeros((2, 2)), {}, "non-finite value .* step 0"),
        (np.zeros((3, 2)), np.zeros((3, 3)), {}, "same number of dimensions; got 2 and 3"),
        (np.zeros((0, 2)), np.zeros((3, 2)), {}, "non-empty"),
        (np.zeros((3, 2)), np.zeros((3, 2)), {"weights": [1.0]}, r"shape \(2,\)"),
        (np.zeros((3, 2)), np.zeros((3, 2)), {"weights": [1.0, -1.0]}, ">= 0"),
    ],
)
def test_dtw_rejects_bad_input(a, b, kwargs, match):
    with pytest.raises(ImitateError, match=match):
        dtw(a, b, **kwargs)


def test_align_rejects_bad_input():
    with pytest.raises(ImitateError, match="at least 2 demonstrations; got 1"):
        align([np.zeros((5, 2))])
    with pytest.raises(ImitateError, match=r"demos\[1\] has 3"):
        align([np.zeros((5, 2)), np.zeros((5, 3))])
    with pytest.raises(ImitateError, match=r"demos\[1\] contains a non-finite"):
        align([np.zeros((5, 2)), np.full((5, 2), np.inf)])
    with pytest.raises(ImitateError, match=r"reference must be in \[0, 1\]; got 5"):
        align([np.zeros((5, 2)), np.ones((5, 2))], reference=5)
