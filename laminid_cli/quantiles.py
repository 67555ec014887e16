"""Quantiles of the normal, Student t and chi-square distributions, in pure Python.

Every identification needs three numbers (the normal and Student t quantiles of its intervals,
the chi-square limit of its fit check); ``scipy.stats`` costs about a second of start-up for them
and even ``scipy.special`` 40 ms, a tenth of what ``laminid identify`` adds to ``laminid modes``.
So each quantile is the root of its distribution function, written with ``math`` alone:

* normal: upper tail Q(x) = erfc(x / sqrt 2) / 2;
* Student t with nu degrees of freedom: upper tail S(t) = I_y(nu/2, 1/2) / 2 for t >= 0, with
  y = nu / (nu + t^2) and I the regularised incomplete beta function (continued fraction);
* chi-square with k degrees of freedom: upper tail Q(k/2, c/2), the regularised upper incomplete
  gamma function (series below c/2 < k/2 + 1, continued fraction above);
* F with (m, n) degrees of freedom: I_x(m/2, n/2), x = m F / (m F + n) (the test of values
  fixed together against a fit with them free, when its variance factor is estimated).

The tail that is solved is the smaller one (no cancellation in 1 - q). Newton's method from the
classical approximations (Abramowitz & Stegun 26.2.23, Cornish-Fisher, Wilson-Hilferty), kept
inside a bracket (bisection when a step leaves it), stops at a relative step of 1e-15. Measured
against scipy.stats (q from 1e-6 to 1 - 1e-6): the normal within 1e-15, t within 5e-13 and
chi-square within 2e-14 up to 1000 degrees of freedom (lgamma's rounding grows with them: 5e-11
at 1e5); from 1e5 degrees of freedom on, t is the Cornish-Fisher expansion itself (within 2e-12:
the continued fraction lost its digits there, 1.5e-6 at 1e10, and Welch-Satterthwaite's
effective degrees of freedom can be that large); tests/test_identify_reduced.py checks 1e-12
and 1e-10, tests/test_cli_startup.py that identify imports neither scipy.stats nor
scipy.special.
"""

from __future__ import annotations

import math

_EPS = 1e-15          # relative step at which the Newton iterations stop
_TINY = 1e-300        # Lentz's guard against a zero denominator
_MAX_TERMS = 100000   # continued-fraction / series terms (tens for the degrees of freedom of a fit)


def norm_ppf(q: float) -> float:
    """Standard normal quantile (scipy.stats.norm.ppf)."""
    bad = _bad(q)
    if bad is not None:
        return bad
    if q == 0.5:
        return 0.0
    p, sign = (1.0 - q, 1.0) if q > 0.5 else (q, -1.0)
    t = math.sqrt(-2.0 * math.log(p))                       # A&S 26.2.23, |error| < 4.5e-4
    x = t - (2.515517 + 0.802853 * t + 0.010328 * t * t) / (
        1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t ** 3)
    x = _newton(lambda v: _norm_sf(v) - p, lambda v: -_norm_pdf(v), x, 0.0, 40.0)
    return sign * x


def t_ppf(q: float, dof: float) -> float:
    """Student t quantile with ``dof`` degrees of freedom (scipy.stats.t.ppf)."""
    bad = _bad(q, dof)
    if bad is not None:
        return bad
    if q == 0.5:
        return 0.0
    p, sign = (1.0 - q, 1.0) if q > 0.5 else (q, -1.0)
    nu = float(dof)
    if nu == 1.0:                                           # Cauchy: closed form
        return sign / math.tan(math.pi * p)
    z = norm_ppf(1.0 - p)
    z2 = z * z                                              # Cornish-Fisher start
    t0 = z + z * (z2 + 1) / (4 * nu) + z * ((5 * z2 + 16) * z2 + 3) / (96 * nu * nu)
    if nu >= 1e5:
        # the expansion's next term is O(nu^-3): ~1e-13 here at q = 1e-6, where the incomplete
        # beta's continued fraction loses its digits (1e10 degrees of freedom: 1.5e-6)
        return sign * t0
    log_norm = 0.5 * math.log(nu) + _log_beta(0.5 * nu, 0.5)
    hi = max(2.0 * t0, 1.0)
    while _t_sf(hi, nu) > p:                                # bracket: S(0) = 1/2 > p
        hi *= 4.0
    t = _newton(lambda v: _t_sf(v, nu) - p,
                lambda v: -math.exp(-0.5 * (nu + 1) * math.log1p(v * v / nu) - log_norm),
                min(max(t0, 0.0), hi), 0.0, hi)
    return sign * t


def chi2_ppf(q: float, dof: float) -> float:
    """Chi-square quantile with ``dof`` degrees of freedom (scipy.stats.chi2.ppf)."""
    bad = _bad(q, dof)
    if bad is not None:
        return bad
    a = 0.5 * float(dof)
    upper = q > 0.5                                         # solve the smaller tail
    p = 1.0 - q if upper else q
    h = 2.0 / (9.0 * dof)                                   # Wilson-Hilferty start
    c0 = dof * max(1.0 - h + norm_ppf(q) * math.sqrt(h), 0.1) ** 3
    lg = math.lgamma(a)

    def f(c):
        lower_tail, upper_tail = _gamma_tails(a, 0.5 * c)
        return (upper_tail if upper else lower_tail) - p

    def df(c):
        d = 0.5 * math.exp((a - 1) * math.log(0.5 * c) - 0.5 * c - lg) if c > 0 else 0.0
        return -d if upper else d

    lo, hi = 0.0, max(2.0 * c0, 1.0)
    while (f(hi) > 0) if upper else (f(hi) < 0):
        hi *= 4.0
    return _newton(f, df, min(c0, hi), lo, hi, increasing=not upper)


def f_ppf(q: float, dfn: float, dfd: float) -> float:
    """F quantile with ``dfn`` and ``dfd`` degrees of freedom (scipy.stats.f.ppf): the
    distribution function is I_x(dfn/2, dfd/2) with x = dfn F / (dfn F + dfd); the smaller
    tail is solved for x (or for y = 1 - x, the upper tail I_y(dfd/2, dfn/2)), so that F =
    dfd x / (dfn y) keeps its digits."""
    bad = _bad(q, min(dfn, dfd))
    if bad is not None:
        return bad
    a, b = 0.5 * float(dfn), 0.5 * float(dfd)
    upper = q > 0.5
    p, (a_s, b_s) = (1.0 - q, (b, a)) if upper else (q, (a, b))
    log_b = _log_beta(a_s, b_s)

    def f(x):                          # the solved tail at x, minus p (increasing in x)
        return _beta_inc(a_s, b_s, x, 1.0 - x) - p

    def df(x):
        if not 0.0 < x < 1.0:
            return 0.0
        return math.exp((a_s - 1.0) * math.log(x) + (b_s - 1.0) * math.log1p(-x) - log_b)

    x = _newton(f, df, 0.5, 0.0, 1.0, increasing=True)
    x, y = (1.0 - x, x) if upper else (x, 1.0 - x)   # x: the lower tail's variable
    return float(dfd) * x / (float(dfn) * y) if y > 0 else math.inf


# --- distribution functions ------------------------------------------------------------------

def _bad(q, dof=1.0):
    """The value of an out-of-range input (as scipy: NaN, or the infinite end), else None."""
    if not (0.0 <= q <= 1.0) or not dof > 0:               # also NaN
        return math.nan
    if q == 0.0:
        return -math.inf
    if q == 1.0:
        return math.inf
    return None


def _norm_sf(x):
    return 0.5 * math.erfc(x / math.sqrt(2.0))


def _norm_pdf(x):
    return math.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi)


def _log_beta(a, b):
    return math.lgamma(a) + math.lgamma(b) - math.lgamma(a + b)


def _t_sf(t, nu):
    """Upper tail of Student t at t >= 0: I_y(nu/2, 1/2) / 2, y = nu / (nu + t^2)."""
    t2 = t * t
    return 0.5 * _beta_inc(0.5 * nu, 0.5, nu / (nu + t2), t2 / (nu + t2))


def _beta_inc(a, b, x, y):
    """Regularised incomplete beta I_x(a, b), y = 1 - x given separately (exact)."""
    if x <= 0.0:
        return 0.0
    if y <= 0.0:
        return 1.0
    if x > (a + 1.0) / (a + b + 2.0):                       # the fraction converges slowly here
        return 1.0 - _beta_inc(b, a, y, x)
    front = math.exp(a * math.log(x) + b * math.log(y) - _log_beta(a, b)) / a
    return front * _lentz(lambda m: _beta_cf_term(a, b, x, m))


def _beta_cf_term(a, b, x, m):
    """The m-th numerator d_m of I's continued fraction 1/(1+ d1/(1+ d2/(1+ ...)))."""
    k = m // 2
    if m % 2:                                               # d_{2k+1}
        return -(a + k) * (a + b + k) * x / ((a + 2 * k) * (a + 2 * k + 1))
    return k * (b - k) * x / ((a + 2 * k - 1) * (a + 2 * k))  # d_{2k}


def _lentz(term):
    """1 / (1 + d1 / (1 + d2 / (1 + ...))) by the modified Lentz method."""
    f = c = 1.0
    d = 0.0
    for m in range(1, _MAX_TERMS):
        dm = term(m)
        d = 1.0 + dm * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + dm / c
        c = c if abs(c) > _TINY else _TINY
        f *= c * d
        if abs(c * d - 1.0) < 1e-16:
            break
    return 1.0 / f


def _gamma_tails(a, x):
    """(P(a, x), Q(a, x)): the regularised lower and upper incomplete gamma functions."""
    if x <= 0.0:
        return 0.0, 1.0
    log_front = a * math.log(x) - x - math.lgamma(a)
    if x < a + 1.0:                                         # series of P
        term = total = 1.0 / a
        ap = a
        for _ in range(_MAX_TERMS):
            ap += 1.0
            term *= x / ap
            total += term
            if abs(term) < abs(total) * 1e-17:
                break
        lower = total * math.exp(log_front)
        return lower, 1.0 - lower
    # continued fraction of Q: e^-x x^a / Gamma(a) * 1 / (x + 1 - a - 1(1-a) / (x + 3 - a - ...))
    b = x + 1.0 - a
    c = 1.0 / _TINY
    d = 1.0 / b
    h = d
    for i in range(1, _MAX_TERMS):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = b + an / c
        c = c if abs(c) > _TINY else _TINY
        h *= d * c
        if abs(d * c - 1.0) < 1e-16:
            break
    upper = math.exp(log_front) * h
    return 1.0 - upper, upper


def _newton(f, df, x, lo, hi, increasing=False):
    """Root of f in [lo, hi] (f decreasing, or increasing) by Newton's method from x, with
    bisection whenever a step leaves the bracket, which every evaluation narrows."""
    for _ in range(200):
        fx = f(x)
        if fx == 0.0:
            return x
        if (fx > 0) != increasing:
            lo = x
        else:
            hi = x
        slope = df(x)
        step = fx / slope if slope != 0 else math.inf
        new = x - step
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        if abs(new - x) <= _EPS * abs(new) or hi - lo <= _EPS * abs(hi):
            return new
        x = new
    return x


def binom_sf(k: int, n: int, p: float) -> float:
    """P(X >= k) for X binomial (n, p) (scipy.stats.binom.sf(k - 1, n, p)): the sum of the
    probabilities of k..n, each from math.lgamma in logarithms (no overflow for large n)."""
    if k <= 0:
        return 1.0
    if k > n:
        return 0.0
    if p <= 0.0 or p >= 1.0:
        return 1.0 if p >= 1.0 else 0.0
    lp, lq = math.log(p), math.log1p(-p)
    lc = math.lgamma(n + 1)
    total = math.fsum(math.exp(lc - math.lgamma(j + 1) - math.lgamma(n - j + 1) + j * lp
                               + (n - j) * lq) for j in range(k, n + 1))
    return min(total, 1.0)


def order_statistic_below(n: int, p: float, level: float) -> int:
    """The largest k (1-based) whose order statistic x_(k) of n independent samples lies at
    or below the p quantile of their (continuous) distribution with probability >= level:
    x_(k) <= q_p exactly when at least k samples are <= q_p, whose count is binomial (n, p),
    so P = P(Bin(n, p) >= k) (:func:`binom_sf`), decreasing in k. 0 when even x_(1) is not
    below q_p with that probability (too few samples).

    A lower confidence bound of the p quantile is x_(k); by symmetry x_(n + 1 - k') with k' of
    (n, 1 - p) is an upper confidence bound of the p quantile. For n = 40, p = 0.975, level
    0.95: k = 37 (P = 0.982; k = 38 gives 0.921); for n = 2, k = 2 (0.975^2 = 0.9506)."""
    k = 0
    lo, hi = 1, n
    while lo <= hi:                        # binary search: P(Bin >= k) falls as k grows
        mid = (lo + hi) // 2
        if binom_sf(mid, n, p) >= level:
            k, lo = mid, mid + 1
        else:
            hi = mid - 1
    return k
