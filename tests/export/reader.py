"""A .skyc reader written from the format alone, independent of `gcs.export.skyc`: unzip,
parse ``show.json``, and evaluate each drone's trajectory (Bezier segments between keyframes,
Bernstein form) at any time, as a show tool plays it."""

from __future__ import annotations

import io
import json
import zipfile
from math import comb
from typing import Any

import numpy as np

__all__ = ["evaluate", "read_show", "velocity"]


def read_show(data: bytes) -> dict[str, Any]:
    """The parsed ``show.json`` of a .skyc archive (which must be a valid ZIP holding it)."""
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert archive.testzip() is None  # every entry's CRC checks
        return json.loads(archive.read("show.json"))


def _segments(trajectory: dict[str, Any]) -> tuple[np.ndarray, list[np.ndarray]]:
    """Absolute keyframe times, and for each segment its Bezier points (start, controls,
    end) as an array (degree + 1, 3)."""
    keyframes = trajectory["points"]
    offset = float(trajectory.get("takeoffTime", 0.0))
    times = np.array([float(k[0]) for k in keyframes]) + offset
    curves = [np.array([keyframes[i - 1][1], *keyframes[i][2], keyframes[i][1]], dtype=float)
              for i in range(1, len(keyframes))]
    return times, curves


def _bernstein(points: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The Bezier curve of `points` (n + 1, 3) at parameters `u` (M,): sum of
    C(n, i) (1 - u)^(n - i) u^i P_i."""
    n = len(points) - 1
    weights = np.stack([comb(n, i) * (1.0 - u) ** (n - i) * u ** i for i in range(n + 1)],
                       axis=1)
    return weights @ points


def evaluate(trajectory: dict[str, Any], times: np.ndarray) -> np.ndarray:
    """Positions (M, 3) at `times`: before the first keyframe its point, after the last the
    last point, between two keyframes the segment that ends at the later one."""
    keytimes, curves = _segments(trajectory)
    out = np.empty((len(times), 3))
    first, last = trajectory["points"][0][1], trajectory["points"][-1][1]
    out[times <= keytimes[0]] = first
    out[times >= keytimes[-1]] = last
    inside = (times > keytimes[0]) & (times < keytimes[-1])
    index = np.searchsorted(keytimes, times, side="right") - 1
    for k in np.unique(index[inside]):
        mask = inside & (index == k)
        u = (times[mask] - keytimes[k]) / (keytimes[k + 1] - keytimes[k])
        out[mask] = _bernstein(curves[k], u)
    return out


def velocity(trajectory: dict[str, Any], times: np.ndarray) -> np.ndarray:
    """Velocities (M, 3) strictly between the first and last keyframes: the derivative of
    each segment's curve divided by its duration (a degree-n Bezier's derivative is the
    degree n - 1 Bezier of n (P_i+1 - P_i))."""
    keytimes, curves = _segments(trajectory)
    index = np.searchsorted(keytimes, times, side="right") - 1
    out = np.empty((len(times), 3))
    for k in np.unique(index):
        mask = index == k
        duration = keytimes[k + 1] - keytimes[k]
        u = (times[mask] - keytimes[k]) / duration
        points = curves[k]
        n = len(points) - 1
        out[mask] = _bernstein(n * np.diff(points, axis=0), u) / duration
    return out
