"""Interval estimates for the workbench's figures: a seeded percentile bootstrap over games.

A sweep plays each setting on the same games as policy ``none``, so a gain is a
per-game *paired* difference; its uncertainty comes from which games were drawn.
:func:`bootstrap_ci` resamples games with replacement (``RESAMPLES`` times, from
``numpy.random.default_rng(SEED)``) and reports the 2.5th and 97.5th percentiles of
the resampled means: the same values give the same interval on every run.
:func:`median_ratio_ci` does the same for a ratio of medians over pairs (the CPU times
of two configurations on the same trials, ``scripts/bench_core.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

RESAMPLES = 10_000
SEED = 0
LEVEL = 0.95


def method(resamples: int = RESAMPLES) -> str:
    """Return how a band or interval is computed, for captions, with the number of resamples used."""
    return f"95 % percentile bootstrap CI over games ({resamples:,} resamples, seed {SEED})"


#: How every band and interval of the workbench is computed at the default number of resamples.
METHOD = method()


@dataclass(frozen=True)
class Estimate:
    """A mean over ``n`` values with its bootstrap confidence interval [low, high]."""

    mean: float
    low: float
    high: float
    n: int

    def text(self, digits: int = 3, signed: bool = False) -> str:
        """Return ``mean [low, high]`` with ``digits`` decimals (signs shown if ``signed``)."""
        form = f"{{:+.{digits}f}}" if signed else f"{{:.{digits}f}}"
        return f"{form.format(self.mean)} [{form.format(self.low)}, {form.format(self.high)}]"

    @property
    def excludes_zero(self) -> bool:
        """Whether the interval lies entirely above or below 0."""
        return self.low > 0 or self.high < 0


def bootstrap_ci(values: Sequence[float], resamples: int = RESAMPLES, seed: int = SEED,
                 level: float = LEVEL) -> Estimate:
    """Return the mean of ``values`` and its percentile bootstrap interval (seeded, so reproducible)."""
    import numpy as np

    data = np.asarray(values, dtype=float)
    n = len(data)
    if n == 0:
        return Estimate(float("nan"), float("nan"), float("nan"), 0)
    mean = float(data.mean())
    if n == 1 or np.all(data == data[0]):
        return Estimate(mean, mean, mean, n)
    rng = np.random.default_rng(seed)
    means = data[rng.integers(0, n, size=(resamples, n))].mean(axis=1)
    tail = (1 - level) / 2 * 100
    low, high = np.percentile(means, [tail, 100 - tail])
    return Estimate(mean, float(low), float(high), n)


def ratio_bootstrap_ci(numerators: Sequence[float], denominators: Sequence[float], resamples: int = RESAMPLES,
                       seed: int = SEED, level: float = LEVEL) -> Estimate:
    """Return sum(numerators) / sum(denominators) and its percentile bootstrap interval over units.

    For a per-item mean of per-unit totals (e.g. log-likelihood per candidate, units = games):
    units are resampled with replacement, as :func:`bootstrap_ci` does (same seed, same draws).
    """
    import numpy as np

    num = np.asarray(numerators, dtype=float)
    den = np.asarray(denominators, dtype=float)
    n = len(num)
    if n == 0 or den.sum() == 0:
        return Estimate(float("nan"), float("nan"), float("nan"), n)
    return _resampled_ratio(num, den, float(num.sum() / den.sum()), np.sum, resamples, seed, level)


def median_ratio_ci(numerators: Sequence[float], denominators: Sequence[float], resamples: int = RESAMPLES,
                    seed: int = SEED, level: float = LEVEL) -> Estimate:
    """Return median(numerators) / median(denominators) and its percentile bootstrap interval over pairs.

    ``numerators[i]`` and ``denominators[i]`` are one pair (e.g. the CPU time of one
    trial under two configurations, same target, measured back to back): pairs are
    resampled with replacement, both members together, as :func:`bootstrap_ci` resamples
    values (same seed, same draws), so what the two share (load on the machine at that
    moment) cancels in each resample's ratio.
    """
    import numpy as np

    num = np.asarray(numerators, dtype=float)
    den = np.asarray(denominators, dtype=float)
    n = len(num)
    if n == 0 or n != len(den) or np.median(den) <= 0:
        return Estimate(float("nan"), float("nan"), float("nan"), n)
    return _resampled_ratio(num, den, float(np.median(num) / np.median(den)), np.median, resamples, seed, level)


def _resampled_ratio(num, den, value: float, statistic, resamples: int, seed: int, level: float) -> Estimate:
    """Return ``value`` with the interval of ``statistic(num) / statistic(den)`` over pairs resampled together."""
    import numpy as np

    n = len(num)
    if n == 1:
        return Estimate(value, value, value, n)
    draws = np.random.default_rng(seed).integers(0, n, size=(resamples, n))
    ratios = statistic(num[draws], axis=1) / np.maximum(statistic(den[draws], axis=1), 1e-300)
    tail = (1 - level) / 2 * 100
    low, high = np.percentile(ratios, [tail, 100 - tail])
    return Estimate(value, float(low), float(high), n)
