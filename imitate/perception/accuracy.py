"""How well the robot saw the demonstrations: tracking errors and demonstrations found, against
the simulation's ground truth."""

from __future__ import annotations

import numpy as np

from imitate.errors import ImitateError
from imitate.perception import Observations

__all__ = ["demo_counts", "tracking_errors"]


def demo_counts(found: np.ndarray, true: np.ndarray) -> dict:
    """Detected and expected demonstrations; the largest boundary error [s] of the matched
    ones (each true demonstration to the detected one nearest in start time).

    Args:
        found: ``(n_found, 2)`` detected start and end times [s].
        true: ``(n_true, 2)`` true start and end times [s].
    """
    nearest = np.abs(found[:, None, 0] - true[None, :, 0]).argmin(axis=0)
    return {
        "detected": len(found),
        "expected": len(true),
        "boundary_err_s_max": float(np.abs(found[nearest] - true).max()),
    }


def tracking_errors(observations: Observations) -> dict:
    """Position [mm] and axis-angle [deg] errors of the tracks against the ground truth (median,
    95th percentile), the fraction of detections and the number of gaps left unfilled."""
    tracks, truth = observations.tracks, observations.truth
    if truth is None:
        raise ImitateError("tracking errors need the ground truth (simulated frames)")
    pos = np.linalg.norm(tracks.position - truth.position, axis=-1) * 1e3
    turn = np.angle(np.exp(1j * (tracks.angle - truth.angle)))
    pos, turn = pos[np.isfinite(pos)], np.degrees(np.abs(turn[np.isfinite(turn)]))
    return {
        "pos_err_mm_median": float(np.median(pos)),
        "pos_err_mm_p95": float(np.percentile(pos, 95)),
        "angle_err_deg_median": float(np.median(turn)),
        "detected_fraction": float(tracks.detected.mean()),
        "long_gaps": len(tracks.long_gaps),
    }
