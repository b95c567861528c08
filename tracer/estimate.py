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
