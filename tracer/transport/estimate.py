"""Estimates with their error: batch means.

A query runs independent batches (each seeded from (seed, batch index)); each batch gives one
estimate per bin (a point, a grid cell). The answer is the mean of the batch estimates and its
standard error is the sample standard deviation of the batch estimates / √(batches). With batches of
equal size this is the textbook batch-means estimator; it needs no assumption about the photons
within a batch, which may be correlated (one photon crossing several sensors).

`Estimate` keeps the running sums in float64 and merges with another (parallel machines, resumed
queries) exactly: merging is addition of the sums.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Estimate:
    """Running batch means of `n_bins` quantities.

    Attributes
    ----------
    total : (n_bins,) float64 — sum of the batch estimates.
    total_sq : (n_bins,) float64 — sum of their squares.
    batches : int — number of batches added.
    """

    total: np.ndarray
    total_sq: np.ndarray
    batches: int = 0

    @classmethod
    def empty(cls, n_bins: int) -> Estimate:
        if n_bins < 0:
            raise ValueError(f"n_bins must be >= 0, got {n_bins}")
        return cls(np.zeros(n_bins), np.zeros(n_bins), 0)

    def add(self, batch_values: np.ndarray) -> None:
        """Add batch estimates, shape (n_batches, n_bins) or (n_bins,); rows are added in order."""
        v = np.atleast_2d(np.asarray(batch_values, dtype=np.float64))
        if v.shape[1] != self.total.shape[0]:
            raise ValueError(f"expected {self.total.shape[0]} bins per batch, got {v.shape[1]}")
        if not np.all(np.isfinite(v)):
            raise ValueError("a batch estimate is not finite")
        for row in v:  # in order: the sums are bit-identical whatever the batching of the calls
            self.total += row
            self.total_sq += row * row
        self.batches += v.shape[0]

    def merge(self, other: Estimate) -> Estimate:
        """The estimate of both sets of batches together."""
        if other.total.shape != self.total.shape:
            raise ValueError(f"cannot merge estimates of {self.total.shape[0]} and {other.total.shape[0]} bins")
        return Estimate(self.total + other.total, self.total_sq + other.total_sq, self.batches + other.batches)

    @property
    def mean(self) -> np.ndarray:
        if self.batches == 0:
            return np.zeros_like(self.total)
        return self.total / self.batches

    @property
    def stderr(self) -> np.ndarray:
        """Standard error of the mean; inf with fewer than 2 batches."""
        b = self.batches
        if b < 2:
            return np.full_like(self.total, np.inf)
        m = self.total / b
        var = np.maximum(self.total_sq / b - m * m, 0.0) * b / (b - 1)
        return np.sqrt(var / b)

    def relative_error(self) -> np.ndarray:
        """stderr / |mean|; inf where the mean is 0 but batches disagree, 0 where all batches gave exactly 0."""
        m, s = np.abs(self.mean), self.stderr
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(m > 0, s / np.where(m > 0, m, 1.0), np.where(s > 0, np.inf, 0.0))
        if self.batches < 2:
            r[:] = np.inf
        return r


COST_TARGETS = (0.05, 0.02, 0.01, 0.005, 0.002)   # relative errors an answer's `cost` predicts the price of


def cost_of(lux: np.ndarray, stderr: np.ndarray, photons: int, seconds: float,
            targets: tuple[float, ...] | list[float] = COST_TARGETS) -> dict:
    """What tighter errors would cost, predicted from a run's own variance and speed: the error of a Monte Carlo
    estimate falls as 1/√photons, so reaching relative error t from r after N photons takes N (r / t)² photons, at
    this run's photons per second (on this scene and this machine).

    lux, stderr : (k,) the run's values and standard errors (any shape; flattened); photons, seconds : what the run
    traced and the seconds it spent tracing (compilation excluded). Returns ``{"targets", "photons_per_second",
    "worst", "median", "dark_points"}``: for the worst and the median relative error over the lit points
    (lux > 0), ``{"relative_error", "photons": [...], "seconds": [...]}`` per target (None where no point is
    lit); `dark_points` counts the points no light reached, where no target means anything.
    """
    v = np.asarray(lux, float).ravel()
    e = np.asarray(stderr, float).ravel()
    lit = (v > 0) & np.isfinite(e)
    rate = photons / seconds if seconds > 0 else float("inf")
    out: dict = {"targets": [float(t) for t in targets], "photons_per_second": float(rate),
                 "dark_points": int(np.count_nonzero(v <= 0)), "worst": None, "median": None}
    if not lit.any() or photons <= 0:
        return out
    rel = e[lit] / v[lit]
    for name, r in (("worst", float(np.max(rel))), ("median", float(np.median(rel)))):
        needed = [photons * (r / t) ** 2 for t in targets]
        out[name] = {"relative_error": r, "photons": [int(math.ceil(n)) for n in needed],
                     "seconds": [n / rate for n in needed]}
    return out
