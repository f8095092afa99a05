"""Exact confidence intervals of the counts the benchmarks report (rates of rare events)."""

from __future__ import annotations


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Return the exact (Clopper-Pearson) confidence interval of a binomial rate ``k / n``.

    (0, 1) for ``n = 0``: nothing measured (a caller should print none).
    """
    from scipy.special import betaincinv

    if n == 0:
        return 0.0, 1.0
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else float(betaincinv(k, n - k + 1, a))
    hi = 1.0 if k == n else float(betaincinv(k + 1, n - k, 1 - a))
    return lo, hi


def poisson_interval(k: int, exposure: float, level: float = 0.95) -> tuple[float, float]:
    """Return the exact (Garwood) confidence interval of a rate of ``k`` events in ``exposure``.

    In events per unit of ``exposure`` (false alarms per taxel-hour: ``exposure`` in
    taxel-hours); ``inf`` above for no exposure.
    """
    from scipy.stats import chi2

    if not exposure > 0:
        return 0.0, float("inf")
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else float(chi2.ppf(a, 2 * k)) / 2.0
    hi = float(chi2.ppf(1 - a, 2 * k + 2)) / 2.0
    return lo / exposure, hi / exposure
