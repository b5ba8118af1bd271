"""A share of yes/no outcomes with its exact 95 % interval: how often, over units or logs,
something held (the Monte Carlo's units at or below the paper's number, the diagnosis's
named effects and false alarms)."""
from scipy.stats import beta


def proportion(flags):
    """{"k", "n", "rate", "ci95"}: k of n flags true, the rate k / n and its 95 %
    Clopper-Pearson interval (exact: the beta quantiles of the binomial; [0, x] at k = 0,
    [x, 1] at k = n); {"k": 0, "n": 0} for no flags."""
    n, k = len(flags), int(sum(bool(f) for f in flags))
    if n == 0:
        return {"k": 0, "n": 0}
    lo = beta.ppf(0.025, k, n - k + 1) if k else 0.0
    hi = beta.ppf(0.975, k + 1, n - k) if k < n else 1.0
    return {"k": k, "n": n, "rate": k / n, "ci95": [float(lo), float(hi)]}
