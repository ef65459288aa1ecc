"""The workbench's interval estimates (fsreg_ros/research/stats.py): the paired ratio of medians."""

from __future__ import annotations

import math

import pytest

from fsreg_ros.research.stats import median_ratio_ci


def test_median_ratio_of_pairs_with_its_interval():
    # Five pairs: medians 3.0 and 2.0.
    estimate = median_ratio_ci([1.0, 2.0, 3.0, 4.0, 50.0], [2.0, 1.0, 2.0, 3.0, 2.0], resamples=2000, seed=1)
    assert estimate.mean == 1.5 and estimate.n == 5
    assert estimate.low <= 1.5 <= estimate.high
    # Every resampled ratio is a ratio of two of the values: the bounds are too.
    assert 1.0 / 3.0 <= estimate.low and estimate.high <= 50.0
    assert median_ratio_ci([1.0, 2.0, 3.0, 4.0, 50.0], [2.0, 1.0, 2.0, 3.0, 2.0], resamples=2000, seed=1) == estimate


def test_pairs_resampled_together_cancel_what_they_share():
    # Each pair shares a factor (load on the machine then): the numerator is always 1.25x the denominator.
    shared = [1.0, 3.0, 0.5, 7.0, 2.0, 1.5, 4.0, 0.8]
    estimate = median_ratio_ci([1.25 * x for x in shared], shared, resamples=500, seed=3)
    assert estimate.mean == pytest.approx(1.25) and estimate.low == pytest.approx(1.25)
    assert estimate.high == pytest.approx(1.25)


def test_degenerate_inputs():
    one = median_ratio_ci([3.0], [2.0])
    assert (one.mean, one.low, one.high, one.n) == (1.5, 1.5, 1.5, 1)
    for num, den in (([], []), ([1.0, 2.0], [1.0]), ([1.0], [0.0])):
        assert math.isnan(median_ratio_ci(num, den).mean)
