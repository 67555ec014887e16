"""Test helpers for Monte Carlo results: :func:`mc_range` builds a MonteCarlo of 40
deterministic "trials" of a given relative spread (as laminid_cli.uncertainty.monte_carlo
would return it), :func:`sure_width` the width its trials show for sure, from scipy.stats.binom
(the reference for MonteCarlo.inner_range)."""

import numpy as np

def unit_trials():
    """40 "trials" of a unit spread: the normal quantiles at (i + 1/2) / 40 (deterministic)."""
    from scipy import stats

    return stats.norm.ppf((np.arange(40) + 0.5) / 40)


def mc_range(u, rel_half, at_lower=None):
    """A MonteCarlo over ``u``'s labels of 40 samples value + rel_half * |value| * t_i (t: the
    normal quantiles at (i + 1/2) / 40), its 95 % range their numpy quantiles, as
    monte_carlo computes it."""
    from laminid_cli.uncertainty import MonteCarlo

    v = np.asarray(u.value, float)
    samples = v + np.outer(unit_trials(), np.asarray(rel_half, float) * np.abs(v))
    p = v.size
    z = np.zeros(p)
    lo, hi = np.quantile(samples, [0.025, 0.975], axis=0)
    return MonteCarlo(labels=u.labels, n_trials=40, n_converged=40, samples=samples,
                      mean=samples.mean(axis=0), std=samples.std(axis=0, ddof=1), lower=lo,
                      upper=hi, linearized_std=u.std, ratio=samples.std(axis=0, ddof=1) / u.std,
                      sigma_factor=1.0, seed=0, jobs=1, time_s=0.0,
                      at_lower_bound=z if at_lower is None else at_lower, at_upper_bound=z)


def sure_width(samples, value, level=0.95, confidence=0.95):
    """The reference for MonteCarlo.inner_range, from scipy.stats.binom: the largest k with
    P(Bin(n, (1 + confidence) / 2) >= k) >= level, the range x_(n + 1 - k) .. x_(k) of the
    sorted samples, as a relative half-width."""
    from scipy import stats

    n = samples.shape[0]
    k = max(j for j in range(1, n + 1)
            if stats.binom.sf(j - 1, n, 0.5 + confidence / 2) >= level)
    x = np.sort(samples)
    return 0.5 * (x[k - 1] - x[n - k]) / abs(value)
