"""Natural frequencies from FRFs: global rational fraction polynomial (RFP) fit.

The estimator of the paper's section 3 (Araujo et al. 2000, ref. [24]): Richardson & Formenti,
"Parameter estimation from frequency response measurements using rational fraction
polynomials", IMAC 1982, in its global multi-FRF form (Richardson & Formenti, "Global curve
fitting of frequency response measurements using the rational fraction polynomial method",
IMAC 1985). Every FRF ``p`` of a band is modelled as

    H_p(s) = N_p(s) / D(s),   s = j omega,

with one denominator ``D`` (shared poles) of degree ``2 N`` (``N`` modes) and a numerator of
``2 N + n_extra`` coefficients per FRF; the extra terms absorb the residual effect of modes
outside the band (mass line below, stiffness line above). The linearised least-squares problem
``min sum_p ||N_p - H_p D||^2`` is written in *Forsythe orthogonal polynomials* (Forsythe 1957,
"Generation and use of orthogonal polynomials for data-fitting with a digital computer"): real
polynomials orthonormal on the symmetric point set {-omega_i, +omega_i} of the band, scaled to
[-1, 1]. With ``theta_k(j x) = j^k phi_k(x)`` they are polynomials in ``s`` with real
coefficients, so poles come in conjugate pairs and the least-squares matrices stay well
conditioned up to high orders. The numerators are eliminated (projection onto the orthogonal
complement of the numerator basis), the denominator is solved with its top coefficient fixed,
and its roots are the eigenvalues of the *comrade matrix* of the three-term recurrence (no
conversion to the ill-conditioned power basis).

A stabilisation sweep over the model order separates physical poles (stable in frequency and
damping from order to order) from computational ones; each stable track gives one mode, its
frequency spread over the stable orders the uncertainty. The sweep is run twice: the second
time the equation errors are weighted by ``1 / |D_1(j omega)|`` built from the first pass's
physical poles (Sanathanan & Koerner 1963, "Transfer function synthesis as a ratio of two
complex polynomials"), which undoes the linearisation's emphasis on the regions far from the
resonances. Finally the poles of each band are polished by an output-error least-squares fit
(variable projection, Golub & Pereyra 1973) in which the modal constants and the residual terms
are linear (LSFD), and modes whose contribution does not rise above the fit residual are
dropped, as are poles whose modal constants lower the residual no more than noise alone does
somewhere in the lines fitted (an extra-sum-of-squares test at a stated false-alarm
probability,
:func:`pole_false_alarm`). The frequencies and damping ratios reported are that fit's
optimum, reached whatever the stabilised poles it starts from, with the neighbouring bands'
poles at their own refined values: they are continuous in the FRF data (the stabilised
estimate, a median over the stable orders, jumps where a pole's stability flag flips; it is
only the start). A pole whose
refinement would leave its bounds is no credible mode and is dropped, as is a second pole that
the refinement brings onto a mode another has found (one mode, listed once).

Automatic bands group the peaks of the summed FRF magnitude (at most four per band) and
overlap; a pole seen by two bands is taken from the one in which it lies farther from the edges.

Symbols: ``freq`` Hz, ``omega`` rad/s, poles ``lam = -zeta omega_n + j omega_n sqrt(1 - zeta^2)``
in rad/s, FRFs ``frf`` complex (n_points, n_freq). Modal constants are the complex residues
``A_r`` of ``H_p(s) = sum_r A_pr / (s - lam_r) + conj(A_pr) / (s - conj(lam_r)) + residuals``
(FRF units x rad/s).

This module is pure numerics: no click, no file formats (except :func:`measured_from_frf_file`,
which delegates reading to :mod:`laminid_cli.frf.io`), no plotting.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from laminid_cli.errors import FrfError

log = logging.getLogger(__name__)

#: fewest frequency lines a band may hold
MIN_BAND_LINES = 8
#: a user band with more resonance peaks than this is fitted as overlapping sub-bands
MAX_PEAKS_PER_BAND = 6
#: range of the highest line of a frequency axis the fit accepts (Hz): far beyond any vibration
#: test either way; outside it the axis is not in Hz (a damaged file's float type, wrong units)
#: and the fit's scaling loses precision (subnormal numbers) or overflows
FIT_TOP_FREQ_HZ = (1e-6, 1e12)
#: range of the largest FRF magnitude the fit accepts (any units): outside it the squared
#: magnitudes of the least-squares fit underflow or overflow
FIT_FRF_MAGNITUDE = (1e-100, 1e100)
#: a band's pole within this many line spacings of its edges is not taken from that band (a
#: pole at the edge stands for the modes beyond it; an overlapping band sees it inside)
EDGE_LINES = 2


# --------------------------------------------------------------------------- data classes
@dataclass(frozen=True)
class PoleCriteria:
    """Options of the fit and how a physical pole is told from a computational one.

    Attributes
    ----------
    freq_tol : relative change of natural frequency between consecutive orders for a pole to be
        "stable in frequency" (0.002 = 0.2 %)
    damping_tol : relative change of damping ratio between consecutive orders for "stable in
        damping"
    max_damping : largest damping ratio a physical mode may have
    min_stable : fewest consecutive orders over which a pole must be stable in frequency and
        damping to be reported as a mode
    min_snr : a mode's peak contribution (|A| / (zeta omega_n), at the best point) must exceed
        ``min_snr`` times the RMS of the fit residual around it (noise floor)
    n_extra : extra numerator terms (out-of-band residuals)
    max_modes : largest number of modes N in the order sweep of a band (``None``: from the
        number of peaks in the band)
    weighting, weight_floor : weighting of the least-squares errors (:func:`fit_weights`)
    reweight : run the sweep twice, the second time with the equation errors weighted by
        ``1 / |D_1|`` built from the first pass's physical poles (:func:`sk_weights`); this
        brings the linearised fit close to an output-error fit near resonances and is what
        makes close modes under noise separable
    sk_iter : Sanathanan-Koerner iterations at every order (reweighting with the order's own
        previous denominator); helps weak modes in narrow bands, costly in wide ones
    refine : polish each band's stable poles by an output-error fit (:func:`refine_poles`)
    gap_search : look for weak modes between the modes found with narrow SK-iterated fits
        (:func:`_gap_search`)
    """

    freq_tol: float = 0.002
    damping_tol: float = 0.20
    max_damping: float = 0.10
    min_stable: int = 5
    min_snr: float = 5.0
    n_extra: int = 2
    max_modes: int | None = None
    weighting: str = "uniform"
    weight_floor: float = 0.1
    reweight: bool = True
    sk_iter: int = 0
    refine: bool = True
    gap_search: bool = True


@dataclass(frozen=True)
class RfpFit:
    """One global RFP fit of one band at one model order.

    Attributes
    ----------
    band_hz : (lo, hi) Hz, the lines used
    n_modes : N, denominator degree 2N
    n_extra : extra numerator terms
    poles : complex (n,) rad/s, roots of the denominator with positive imaginary part, sorted
    denominator : float (2N+1,), coefficients in the orthonormal basis (top one = 1)
    """

    band_hz: tuple[float, float]
    n_modes: int
    n_extra: int
    poles: np.ndarray
    denominator: np.ndarray

    @property
    def freq_hz(self) -> np.ndarray:
        return np.abs(self.poles) / (2 * np.pi)

    @property
    def damping_ratio(self) -> np.ndarray:
        return -self.poles.real / np.abs(self.poles)


@dataclass(frozen=True)
class Stabilisation:
    """A stabilisation chart: every pole of every order of one band.

    Attributes (all (n,), one entry per pole)
    ----------
    band_hz : (lo, hi) Hz of the fitted lines
    order : N of the model (denominator degree 2N)
    freq_hz : natural frequency, Hz
    damping_ratio : damping ratio (negative = unstable pole)
    stable : 0 new/unstable, 1 stable in frequency, 2 stable in frequency and damping
        (with respect to the previous order, :class:`PoleCriteria`)
    track : id of the pole track across orders (consecutive-order chains), -1 when none
    """

    band_hz: tuple[float, float]
    order: np.ndarray
    freq_hz: np.ndarray
    damping_ratio: np.ndarray
    stable: np.ndarray
    track: np.ndarray


@dataclass(frozen=True)
class Mode:
    """One identified mode.

    Attributes
    ----------
    freq_hz : natural frequency omega_n / 2 pi, Hz
    damping_ratio : zeta (viscous), dimensionless
    modal_constants : complex (n_points,), residue A_pr of each FRF (FRF units x rad/s)
    freq_std_hz : standard deviation of freq_hz over the stable orders, Hz (uncertainty)
    damping_std : standard deviation of the damping ratio over the stable orders
    orders_stable : number of model orders over which the pole was stable
    band_hz : band (lo, hi) the mode was found in, Hz
    snr : peak modal contribution over the local residual RMS
    false_alarm : the probability that noise alone gives a pole whose modal constants lower the
        residual as much as this mode's anywhere in the lines fitted (:func:`pole_false_alarm`;
        at most :data:`FALSE_ALARM`, 0 to the precision of a float for a clear mode)
    """

    freq_hz: float
    damping_ratio: float
    modal_constants: np.ndarray
    freq_std_hz: float
    damping_std: float
    orders_stable: int
    band_hz: tuple[float, float]
    snr: float = np.inf
    false_alarm: float = np.nan

    @property
    def pole(self) -> complex:
        w = 2 * np.pi * self.freq_hz
        z = self.damping_ratio
        return complex(-z * w, w * np.sqrt(max(1.0 - z * z, 0.0)))

    def as_dict(self) -> dict:
        return {"freq_hz": self.freq_hz, "freq_std_hz": self.freq_std_hz,
                "damping_ratio": self.damping_ratio, "damping_std": self.damping_std,
                "orders_stable": self.orders_stable, "band_hz": list(self.band_hz),
                "snr": self.snr, "false_alarm": self.false_alarm,
                "modal_constants": [[float(a.real), float(a.imag)] for a in self.modal_constants]}


@dataclass(frozen=True)
class BandFit:
    """The fit of one band: its stabilisation chart and the LSFD model of its lines.

    Attributes
    ----------
    band_hz : (lo, hi) Hz of the fitted lines
    chart : the band's :class:`Stabilisation`
    poles : complex (n,), rad/s, every pole in the LSFD model (the band's modes first, then
        neighbouring bands' modes)
    constants : complex (n_points, n), their residues
    residual : float (n_points, len(RESIDUAL_POWERS)), coefficients of ``(s / w_ref)^k``
    w_ref : rad/s
    """

    band_hz: tuple[float, float]
    chart: Stabilisation
    poles: np.ndarray
    constants: np.ndarray
    residual: np.ndarray
    w_ref: float

    def synthesise(self, freq) -> np.ndarray:
        """The fitted FRFs (n_points, n_freq) on ``freq`` (Hz, no 0 Hz line)."""
        freq = np.asarray(freq, dtype=float)
        with np.errstate(all="ignore"):
            B = lsfd_basis(freq, self.poles, self.w_ref)
        n = self.poles.size
        X = np.empty((self.constants.shape[0], 2 * n), dtype=float)
        X[:, 0::2], X[:, 1::2] = self.constants.real, self.constants.imag
        return np.hstack([X, self.residual]) @ B.T


@dataclass(frozen=True)
class DroppedPole:
    """A stable pole the fit dropped as no credible mode, and why.

    freq_hz, damping_ratio : the pole when it was dropped (refined; for 'reach' its stabilised
        start); band_hz : the band whose fit dropped it; reason : 'reach' (its output-error
        refinement would leave its bounds, :data:`REFINE_LIMITS`), 'noise' (peak contribution
        below ``min_snr`` times the residual), 'chance' (its modal constants lower the residual
        no more than noise does somewhere in the lines fitted: :func:`pole_false_alarm`) or
        'twice' (a
        mode another pole found: :data:`SAME_MODE_BANDWIDTHS`); why : one sentence with the
        figures; false_alarm : the probability of :func:`pole_false_alarm` where computed
    """

    freq_hz: float
    damping_ratio: float
    band_hz: tuple[float, float]
    reason: str
    why: str
    false_alarm: float | None = None

    def as_dict(self) -> dict:
        return {"freq_hz": self.freq_hz, "damping_ratio": self.damping_ratio,
                "band_hz": list(self.band_hz), "reason": self.reason, "why": self.why,
                "false_alarm": self.false_alarm}


@dataclass(frozen=True)
class ModalFit:
    """Result of :func:`find_modes`: the modes of all bands and how they were found.

    Attributes
    ----------
    modes : identified modes sorted by frequency
    bands : one :class:`BandFit` per band
    criteria : the criteria used
    beyond : modes found above the ``n_modes`` lowest that :func:`find_modes` was asked
        for (``--modes``), not in ``modes``
    out_of_reach : frequencies (Hz, stabilised) of the stable poles dropped because their
        output-error refinement would leave its bounds (:data:`REFINE_LIMITS`)
    dropped : the stable poles dropped as no credible modes (:class:`DroppedPole`), by
        frequency
    """

    modes: tuple[Mode, ...]
    bands: tuple[BandFit, ...]
    criteria: PoleCriteria = field(default_factory=PoleCriteria)
    beyond: tuple[Mode, ...] = ()
    out_of_reach: tuple = ()
    dropped: tuple = ()

    @property
    def freq_hz(self) -> np.ndarray:
        return np.array([m.freq_hz for m in self.modes])

    @property
    def freq_std_hz(self) -> np.ndarray:
        return np.array([m.freq_std_hz for m in self.modes])

    @property
    def damping_ratio(self) -> np.ndarray:
        return np.array([m.damping_ratio for m in self.modes])


#: powers k of the residual terms (s / omega_hi)^k in the LSFD fit: mass line (-2), mobility
#: mass line (-1), constant (0), stiffness-like upper residual terms (1, 2)
RESIDUAL_POWERS = (-2, -1, 0, 1, 2)


# --------------------------------------------------------------------------- polynomials
def forsythe_basis(x, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Forsythe orthonormal polynomials on the symmetric point set {-x_i, +x_i}.

    Three-term recurrence ``x phi_k = gamma_{k+1} phi_{k+1} + gamma_k phi_{k-1}`` (the
    diagonal term vanishes by symmetry, so ``phi_k`` is even/odd with k).

    Parameters
    ----------
    x : float (n_x,), points (normally omega / omega_max in (0, 1])
    n : number of polynomials, degrees 0..n-1

    Returns
    -------
    phi : float (n, n_x), values at x; rows orthonormal in the sum over the *positive* points
        within each parity (``phi_k . phi_l = delta_kl`` for k - l even)
    gamma : float (n + 1,), recurrence coefficients (gamma[0] = 0)

    >>> x = np.linspace(0.1, 1.0, 50)
    >>> phi, g = forsythe_basis(x, 4)
    >>> bool(np.allclose(phi[::2] @ phi[::2].T, np.eye(2)))
    True
    """
    x = np.asarray(x, dtype=float)
    phi = np.empty((n, x.size))
    gamma = np.zeros(n + 1)
    phi[0] = 1.0 / np.sqrt(x.size)
    prev = np.zeros_like(x)
    for k in range(n):
        v = x * phi[k] - gamma[k] * prev
        g = np.sqrt(v @ v)
        gamma[k + 1] = g
        if k + 1 < n:
            prev = phi[k]
            phi[k + 1] = v / g
    return phi, gamma


def comrade_roots(coef, gamma) -> np.ndarray:
    """Roots in s of ``D(s) = sum_k coef[k] theta_k(s)``, ``theta_k(j x) = j^k phi_k(x)``.

    The recurrence in s is ``s theta_k = gamma_{k+1} theta_{k+1} - gamma_k theta_{k-1}``; at a
    root the top polynomial is eliminated with ``D = 0``, so the roots are the eigenvalues of
    this tridiagonal-plus-last-row (comrade) matrix.

    Parameters
    ----------
    coef : float (n + 1,), coefficients of theta_0..theta_n (coef[n] != 0)
    gamma : float (>= n + 1,), from :func:`forsythe_basis`
    """
    coef = np.asarray(coef, dtype=float)
    n = coef.size - 1
    C = np.zeros((n, n))
    k = np.arange(n - 1)
    C[k, k + 1] = gamma[k + 1]
    C[k + 1, k] = -gamma[k + 1]
    C[n - 1, :] -= gamma[n] * coef[:n] / coef[n]
    return np.linalg.eigvals(C)


# --------------------------------------------------------------------------- one band
class _BandSystem:
    """Least-squares matrices of one band, built once for the highest order of the sweep.

    ``fit(n, sk_iter)`` optionally refines the order-n denominator by Sanathanan-Koerner
    iterations: the equation errors are reweighted with ``1 / |D_prev(j omega)|`` of the
    previous iterate (evaluated from its orthonormal-basis coefficients, no roots needed) and
    the order-n matrices rebuilt.
    """

    def __init__(self, freq, frf, band, max_modes: int, n_extra: int,
                 weighting: str = "uniform", weight_floor: float = 0.1, ref_poles=None):
        freq = np.asarray(freq, dtype=float)
        lo, hi = band
        sel = (freq >= lo) & (freq <= hi) & (freq > 0)
        self.freq = freq[sel]
        self.frf = np.asarray(frf)[:, sel]
        self.band = (float(self.freq[0]), float(self.freq[-1]))
        self.w_hi = 2 * np.pi * self.freq[-1]
        x = self.freq / self.freq[-1]
        self.n_extra = n_extra
        n_poly = 2 * max_modes + max(n_extra, 1)
        self.phi, self.gamma = forsythe_basis(x, n_poly)
        # real stacking [Re; Im] of theta_k = j^k phi_k: even k in the real half, odd k in the
        # imaginary half, sign (-1)^(k//2)
        sign = (-1.0) ** (np.arange(n_poly) // 2)
        nf = x.size
        P = np.zeros((2 * nf, n_poly))
        P[:nf, 0::2] = (sign[0::2, None] * self.phi[0::2]).T
        P[nf:, 1::2] = (sign[1::2, None] * self.phi[1::2]).T
        self.P = P
        self.theta = (1j ** np.arange(n_poly))[:, None] * self.phi     # (n_poly, nf)
        scale = np.sqrt(np.mean(np.abs(self.frf) ** 2)) or 1.0
        self.Hs = self.frf / scale
        w = fit_weights(self.Hs, weighting, weight_floor)              # (n_p, nf)
        if ref_poles is not None and len(ref_poles):
            w = w * sk_weights(self.freq, ref_poles)[None, :]
        self.w0 = w
        uniform = weighting == "uniform" and (ref_poles is None or not len(ref_poles))
        self.G, self.WW = self._matrices(w, n_poly, orthonormal=uniform)

    def _matrices(self, w, n_cols: int, orthonormal: bool = False):
        """G_p = Q_p^T W_p (n_p, n_cols, n_cols) and sum_p W_p^T W_p for weights w (n_p, nf)."""
        w2 = np.concatenate([w, w], axis=1)[:, :, None]                # rows [Re; Im]
        HQ = self.Hs[:, None, :] * self.theta[None, :n_cols, :]        # (n_p, n_cols, nf)
        # W_p = weighted [Re; Im] of H_p theta_k, (n_p, 2 nf, n_cols)
        W = w2 * np.concatenate([HQ.real, HQ.imag], axis=2).transpose(0, 2, 1)
        P = self.P[:, :n_cols]
        if orthonormal:
            G = np.matmul(P.T, W)
        else:
            # the weighted numerator basis of each FRF, re-orthonormalised (its first m columns
            # span the weighted polynomials of degree < m: Forsythe with weight w_p^2)
            Qp, Rp = np.linalg.qr(w2 * P[None, :, :])
            Qp = Qp * np.sign(np.diagonal(Rp, axis1=1, axis2=2))[:, None, :]
            G = np.matmul(Qp.transpose(0, 2, 1), W)
        Wf = W.reshape(-1, n_cols)
        return G, Wf.T @ Wf

    @staticmethod
    def _solve(G, WW, n: int, m: int) -> np.ndarray:
        # reduced normal matrix after eliminating the numerators (Q_p orthonormal):
        # M = sum_p W_p^T (I - Q_p Q_p^T) W_p = sum_p W_p^T W_p - G_p^T G_p
        Gm = G[:, :m, : n + 1].reshape(-1, n + 1)
        M = WW[: n + 1, : n + 1] - Gm.T @ Gm
        # min b^T M b with b[n] = 1
        return np.append(_solve_sym(M[:n, :n], -M[:n, n]), 1.0)

    def fit(self, n_modes: int, sk_iter: int = 0) -> RfpFit:
        n = 2 * n_modes
        m = n + self.n_extra
        coef = self._solve(self.G, self.WW, n, m)
        n_cols = max(n + 1, m)
        for _ in range(sk_iter):
            D = np.abs(coef @ self.theta[: n + 1])
            w = self.w0 / np.maximum(D, 1e-12 * D.max())[None, :]
            G, WW = self._matrices(w / np.sqrt(np.mean(w ** 2)), n_cols)
            coef = self._solve(G, WW, n, m)
        s = comrade_roots(coef, self.gamma)
        lam = s * self.w_hi
        lam = lam[lam.imag > 0]
        lam = lam[np.argsort(lam.imag)]
        return RfpFit(band_hz=self.band, n_modes=n_modes, n_extra=self.n_extra, poles=lam,
                      denominator=coef)


#: weightings of the least-squares errors, see :func:`fit_weights`
WEIGHTINGS = ("relative", "uniform")


def fit_weights(frf, weighting: str = "relative", floor: float = 0.1) -> np.ndarray:
    """Weights (n_points, n_freq) of the fit errors of each FRF line.

    ``"uniform"``: 1 (plain Richardson-Formenti, strong peaks dominate). ``"relative"``:
    ``1 / sqrt(|H|^2 + (floor * rms_p)^2)``, i.e. relative errors, as for FRF estimates whose
    noise is proportional to the FRF (coherence-limited); the floor (a fraction of the FRF's
    RMS over the band) stops antiresonances, where additive noise dominates, from taking over.
    Weak modes get their fair share of the fit this way.
    """
    if weighting not in WEIGHTINGS:
        raise FrfError(f"weighting {weighting!r}: expected one of {', '.join(WEIGHTINGS)}")
    mag = np.abs(frf)
    if weighting == "uniform":
        return np.ones(mag.shape)
    rms = np.sqrt(np.mean(mag ** 2, axis=1, keepdims=True))
    w = 1.0 / np.sqrt(mag ** 2 + (floor * rms) ** 2 + 1e-300)
    return w / np.sqrt(np.mean(w ** 2))


def sk_weights(freq, poles) -> np.ndarray:
    """Sanathanan-Koerner weights ``1 / |D_ref(j omega)|`` (n_freq,), normalised to RMS 1.

    ``D_ref`` has the given poles (rad/s) and their conjugates. Weighting the linearised RFP
    equation ``N - H D`` by it turns it into (nearly) the output error ``N / D - H``, so the
    regions near resonances, where the modes are seen, get their due weight instead of the
    edges of the band (Sanathanan & Koerner 1963).
    """
    s = 2j * np.pi * np.asarray(freq, dtype=float)[:, None]
    lam = np.asarray(poles, dtype=complex)[None, :]
    scale = np.abs(lam)
    with np.errstate(all="ignore"):
        logd = np.sum(np.log(np.abs((s - lam) / scale)) + np.log(np.abs((s - lam.conj()) / scale)),
                      axis=1)
    logw = -(logd - logd.max())
    w = np.exp(logw - logw.max())
    return w / np.sqrt(np.mean(w ** 2))


def _solve_sym(M, y):
    """Solve the symmetric M b = y (least-squares fallback if M is singular)."""
    try:
        return np.linalg.solve(M, y)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(M, y, rcond=None)[0]


def _check_arrays(freq, frf):
    from laminid_cli.frf.store import validate_frf_arrays

    freq = np.asarray(freq, dtype=float)
    frf = np.asarray(frf)
    if frf.ndim == 1:
        frf = frf[None, :]
    validate_frf_arrays(freq, frf)
    if frf.shape[0] == 0:
        raise FrfError("no FRFs to fit (0 measurement points)")
    lo, hi = FIT_TOP_FREQ_HZ
    if not lo <= freq[-1] <= hi:
        raise FrfError(f"the frequency axis ends at {freq[-1]:g} Hz, outside {lo:g}-{hi:g} Hz: "
                       "not a frequency axis in Hz (wrong units or a damaged file)")
    peak = float(np.max(np.abs(frf)))
    lo, hi = FIT_FRF_MAGNITUDE
    if not lo <= peak <= hi:
        raise FrfError(("every FRF value is zero" if peak == 0 else
                        f"the largest FRF magnitude is {peak:g}, outside {lo:g}-{hi:g}")
                       + ": nothing to fit (a damaged file?)")
    return freq, frf.astype(complex)


def lines_needed(n_modes: int, n_extra: int, n_points: int) -> int:
    """Fewest lines of a band for a global RFP fit of ``n_modes`` modes to ``n_points`` FRFs.

    Real unknowns: 2N + n_extra numerator coefficients per FRF and 2N shared denominator ones,
    against 2 n_lines real equations per FRF, and one line more (strictly overdetermined).
    """
    return int(np.ceil((2 * n_modes + n_extra + 2 * n_modes / max(n_points, 1)) / 2)) + 1


def max_band_modes(n_lines: int, n_extra: int, n_points: int) -> int:
    """Most modes a band of ``n_lines`` lines can be fitted with (:func:`lines_needed`); the
    order sweep stops there, so it never asks the band for more than it holds."""
    n = max(int(n_lines * n_points / (n_points + 1)) + 2, 0)    # need(N) > N (1 + 1/n_points)
    while n > 0 and lines_needed(n, n_extra, n_points) > n_lines:
        n -= 1
    return n


def _check_band(freq, band, n_modes: int, n_extra: int, n_points: int):
    lo, hi = float(band[0]), float(band[1])
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
        raise FrfError(f"band {lo:g}:{hi:g} Hz is empty (upper edge must exceed the lower)")
    sel = (freq >= lo) & (freq <= hi) & (freq > 0)
    n_lines = int(sel.sum())
    if n_lines < MIN_BAND_LINES:
        raise FrfError(f"band {lo:g}:{hi:g} Hz holds {n_lines} frequency lines of the FRF axis "
                       f"({freq[0]:g}-{freq[-1]:g} Hz, {freq[1] - freq[0]:g} Hz step); at least "
                       f"{MIN_BAND_LINES} are needed")
    need = lines_needed(n_modes, n_extra, n_points)
    if n_lines < need:
        raise FrfError(f"band {lo:g}:{hi:g} Hz holds {n_lines} lines, too few for {n_modes} "
                       f"modes (at least {need} lines needed); widen the band or ask fewer modes")
    return n_lines


def fit_rfp(freq, frf, n_modes: int, *, band=None, n_extra: int = 2) -> RfpFit:
    """Global RFP fit of all FRFs with ``n_modes`` shared pole pairs over one band.

    Parameters
    ----------
    freq : float (n_freq,), Hz, strictly increasing
    frf : complex (n_points, n_freq) (or (n_freq,) for one FRF)
    n_modes : N, the denominator has degree 2N
    band : (lo, hi) Hz; default the whole axis (a 0 Hz line is always skipped)
    n_extra : numerator terms beyond 2N (out-of-band residuals)

    Returns
    -------
    RfpFit (all 2N roots; the ones with positive imaginary part are listed)

    References: Richardson & Formenti 1982 (RFP with orthogonal polynomials); Richardson &
    Formenti 1985 (global multi-FRF fit, common denominator).
    """
    freq, frf = _check_arrays(freq, frf)
    band = (freq[0], freq[-1]) if band is None else band
    if n_modes < 1:
        raise FrfError(f"n_modes must be at least 1 (got {n_modes})")
    _check_band(freq, band, n_modes, n_extra, frf.shape[0])
    with np.errstate(all="ignore"):
        return _BandSystem(freq, frf, band, n_modes, n_extra).fit(n_modes)


# --------------------------------------------------------------------------- stabilisation
def stabilisation(freq, frf, band, orders, *, criteria: PoleCriteria = PoleCriteria(),
                  ref_poles=None) -> Stabilisation:
    """Poles of the global RFP fit of one band at every model order, linked across orders.

    Parameters
    ----------
    freq : float (n_freq,), Hz
    frf : complex (n_points, n_freq)
    band : (lo, hi) Hz of the lines to fit
    orders : increasing numbers of modes N to fit (denominator degree 2N)
    criteria : stability tolerances (:class:`PoleCriteria`)
    ref_poles : complex, rad/s, poles of a previous pass for Sanathanan-Koerner weighting
        (:func:`sk_weights`); ``None`` for the plain linearised fit

    A pole at order N is linked to the nearest pole (in frequency) at order N-1 when that one
    is also its nearest at order N (mutual nearest neighbours); the link is "stable in frequency"
    when the relative change is below ``freq_tol`` and "stable in frequency and damping" when
    the damping changes by less than ``damping_tol`` (relative). Linked poles share a track id.
    Only poles inside the band are kept.
    """
    freq, frf = _check_arrays(freq, frf)
    orders = [int(n) for n in orders]
    if not orders or min(orders) < 1:
        raise FrfError("orders must be a non-empty list of positive numbers of modes")
    _check_band(freq, band, max(orders), criteria.n_extra, frf.shape[0])
    with np.errstate(all="ignore"):
        system = _BandSystem(freq, frf, band, max(orders), criteria.n_extra,
                             criteria.weighting, criteria.weight_floor, ref_poles)
        lo, hi = system.band
        cols = {k: [] for k in ("order", "freq_hz", "damping_ratio", "stable", "track")}
        prev_f = prev_z = prev_t = None
        next_track = 0
        for n in orders:
            fit = system.fit(n, criteria.sk_iter)
            f, z = fit.freq_hz, fit.damping_ratio
            keep = (f >= lo) & (f <= hi) & np.isfinite(f)
            f, z = f[keep], z[keep]
            stable = np.zeros(f.size, dtype=np.int8)
            track = np.full(f.size, -1, dtype=int)
            if prev_f is not None and prev_f.size and f.size:
                d = np.abs(f[:, None] - prev_f[None, :])              # (new, old)
                j = np.argmin(d, axis=1)
                mutual = np.argmin(d, axis=0)[j] == np.arange(f.size)
                rel_f = d[np.arange(f.size), j] / f
                rel_z = np.abs(z - prev_z[j]) / np.maximum(np.abs(z), 1e-12)
                ok_f = mutual & (rel_f < criteria.freq_tol)
                ok_z = ok_f & (rel_z < criteria.damping_tol)
                stable[ok_f] = 1
                stable[ok_z] = 2
                track[ok_f] = np.where(prev_t[j[ok_f]] >= 0, prev_t[j[ok_f]], -1)
            fresh = track < 0
            track[fresh] = next_track + np.arange(int(fresh.sum()))
            next_track += int(fresh.sum())
            for key, val in (("order", np.full(f.size, n)), ("freq_hz", f),
                             ("damping_ratio", z), ("stable", stable), ("track", track)):
                cols[key].append(val)
            prev_f, prev_z, prev_t = f, z, track
    cat = {k: (np.concatenate(v) if v else np.array([])) for k, v in cols.items()}
    return Stabilisation(band_hz=system.band, order=cat["order"].astype(int),
                         freq_hz=cat["freq_hz"], damping_ratio=cat["damping_ratio"],
                         stable=cat["stable"].astype(np.int8), track=cat["track"].astype(int))


@dataclass(frozen=True)
class _Candidate:
    freq_hz: float
    damping_ratio: float
    freq_std_hz: float
    damping_std: float
    orders_stable: int
    top_order: int
    tracks: tuple = ()          # the chart's track ids it was made of


def select_poles(chart: Stabilisation, *, criteria: PoleCriteria = PoleCriteria()
                 ) -> list[_Candidate]:
    """Physical poles of a stabilisation chart, one per mode, sorted by frequency.

    A track qualifies when at least ``min_stable`` of its links are stable in frequency and
    damping and its damping is in (0, max_damping]. Tracks that never coexist at one order and
    whose frequencies agree within ``freq_tol`` are one pole (a broken chain) and are merged;
    coexisting tracks are distinct modes however close (close modes). The estimate is the
    median over the stable poles of the upper half of the orders (where :func:`find_modes`
    starts its refinement from); the uncertainty is the standard deviation over all stable
    poles.
    """
    tracks = chart.track
    ids, inverse = np.unique(tracks[tracks >= 0], return_inverse=True)
    rows = np.flatnonzero(tracks >= 0)
    groups = [rows[inverse == i] for i in range(ids.size)]
    # merge broken chains: same frequency, never at the same order
    med = [float(np.median(chart.freq_hz[g])) for g in groups]
    merged: list[list] = []          # [median Hz, set of orders, index array]
    for i in np.argsort(med):
        g, orders_g = groups[i], set(chart.order[groups[i]].tolist())
        for item in reversed(merged):
            if (med[i] - item[0]) / item[0] >= criteria.freq_tol:
                merged.append([med[i], orders_g, g])
                break
            if not (item[1] & orders_g):
                item[2] = np.concatenate([item[2], g])
                item[1] |= orders_g
                break
        else:
            merged.append([med[i], orders_g, g])
    merged = [item[2] for item in merged]
    out = []
    for g in merged:
        stab = g[chart.stable[g] == 2]
        z = chart.damping_ratio[stab]
        if stab.size < criteria.min_stable:
            continue
        zmed = float(np.median(z))
        if not (0 < zmed <= criteria.max_damping):
            continue
        orders = chart.order[stab]
        top = stab[orders >= np.median(orders)]
        f_all = chart.freq_hz[stab]
        out.append(_Candidate(
            freq_hz=float(np.median(chart.freq_hz[top])),
            damping_ratio=float(np.median(chart.damping_ratio[top])),
            freq_std_hz=float(np.std(f_all, ddof=1)) if f_all.size > 1 else 0.0,
            damping_std=float(np.std(z, ddof=1)) if z.size > 1 else 0.0,
            orders_stable=int(stab.size), top_order=int(orders.max()),
            tracks=tuple(int(t) for t in np.unique(chart.track[g]))))
    out.sort(key=lambda c: c.freq_hz)
    return out


@dataclass(frozen=True)
class UnlistedPoles:
    """Poles of a band's stabilisation chart that are stable in frequency and damping but
    are none of the fit's modes, and why (:func:`unlisted_stable_poles`).

    band : index of the band in ``ModalFit.bands``; rows : indices into its chart's arrays;
    freq_hz : (low, high) of their frequencies; orders : (low, high) model orders;
    n_stable : orders at which their track is stable in frequency and damping; reason :
    'few' (fewer than ``min_stable``: a computational pole), 'edge' (within
    :data:`EDGE_LINES` lines of the band's edge), 'damping' (outside (0, max_damping]) or
    'noise' (its contribution did not rise above the fit residual, ``min_snr``) or 'chance'
    (its modal constants lower the residual no more than noise does somewhere in the lines
    fitted,
    :func:`pole_false_alarm`) or
    'reach' (its output-error refinement would leave its bounds, :data:`REFINE_LIMITS`) or
    'beyond' (a mode, above the ``n_modes`` lowest asked for: ``ModalFit.beyond``); edge_hz :
    the band edge it lies near (within 5 % of the band's width), or None
    """

    band: int
    rows: np.ndarray
    freq_hz: tuple[float, float]
    orders: tuple[int, int]
    n_stable: int
    reason: str
    edge_hz: float | None


def unlisted_stable_poles(fit: ModalFit, freq) -> list[UnlistedPoles]:
    """The poles of ``fit``'s stabilisation charts stable in frequency and damping (the
    chart's x) that lie on none of its modes (within 1 % or two lines), grouped by track,
    with the rule that left each out: what a reader of the chart otherwise has to guess.
    ``freq`` : the FRF's lines, Hz (the edge margin is :data:`EDGE_LINES` of their spacing).
    """
    crit = fit.criteria
    df = float(np.median(np.diff(np.asarray(freq, float))))
    margin = EDGE_LINES * df
    listed = fit.freq_hz
    beyond = np.array([m.freq_hz for m in getattr(fit, "beyond", ())])
    reach = np.array(getattr(fit, "out_of_reach", ()), float)
    chance = np.array([d.freq_hz for d in getattr(fit, "dropped", ()) if d.reason == "chance"])
    out = []
    for k, band in enumerate(fit.bands):
        ch = band.chart
        lo, hi = ch.band_hz
        qualified = {t: c for c in select_poles(ch, criteria=crit) for t in c.tracks}
        rows = np.flatnonzero(ch.stable == 2)
        if listed.size:
            near = np.min(np.abs(ch.freq_hz[rows, None] - listed[None, :]), axis=1)
            rows = rows[near > np.maximum(0.01 * ch.freq_hz[rows], 2 * df)]
        for t in np.unique(ch.track[rows]):
            mine = rows[ch.track[rows] == t]
            track = np.flatnonzero((ch.track == t) & (ch.stable == 2))
            c = qualified.get(int(t))
            if c is None:
                zmed = float(np.median(ch.damping_ratio[track]))
                reason = ("damping" if track.size >= crit.min_stable
                          and not 0 < zmed <= crit.max_damping else "few")
                n_stable = int(track.size)
            elif beyond.size and np.min(np.abs(beyond - c.freq_hz)) <= max(
                    0.01 * c.freq_hz, 2 * df):
                # a mode the fit found, left out by --modes N (it was said to be noise, next
                # to the tallest peak of the band)
                reason = "beyond"
                n_stable = c.orders_stable
            else:
                reason = ("edge" if not lo + margin <= c.freq_hz <= hi - margin
                          else "reach" if np.any(np.abs(reach - c.freq_hz)
                                                 <= crit.freq_tol * c.freq_hz)
                          else "chance" if np.any(np.abs(chance - c.freq_hz)
                                                  <= max(0.01 * c.freq_hz, 2 * df))
                          else "noise")
                n_stable = c.orders_stable
            f = ch.freq_hz[mine]
            near_edge = [e for e in (lo, hi) if abs(np.median(f) - e) <= 0.05 * (hi - lo)]
            out.append(UnlistedPoles(
                band=k, rows=mine, freq_hz=(float(f.min()), float(f.max())),
                orders=(int(ch.order[mine].min()), int(ch.order[mine].max())),
                n_stable=n_stable, reason=reason,
                edge_hz=float(near_edge[0]) if near_edge else None))
    out.sort(key=lambda u: u.freq_hz[0])
    return out


# --------------------------------------------------------------------------- modal constants
def _pole(f_hz, zeta):
    w = 2 * np.pi * np.asarray(f_hz, dtype=float)
    z = np.asarray(zeta, dtype=float)
    return -z * w + 1j * w * np.sqrt(np.clip(1 - z * z, 0, None))


def lsfd_basis(freq, poles, w_ref: float) -> np.ndarray:
    """Complex basis (n_freq, 2 n_poles + n_res) of the LSFD model (real coefficients).

    Columns 2r, 2r+1: ``1/(s-lam) + 1/(s-lam*)`` and ``j/(s-lam) - j/(s-lam*)`` (coefficients
    Re A_r, Im A_r); then ``(s / w_ref)^k`` for k in :data:`RESIDUAL_POWERS`.
    """
    s = 2j * np.pi * np.asarray(freq, dtype=float)[:, None]
    lam = np.asarray(poles, dtype=complex)[None, :]
    a, b = 1.0 / (s - lam), 1.0 / (s - lam.conj())
    modal = np.empty((s.shape[0], 2 * lam.shape[1]), dtype=complex)
    modal[:, 0::2] = a + b
    modal[:, 1::2] = 1j * (a - b)
    res = (s / w_ref) ** np.array(RESIDUAL_POWERS)[None, :]
    return np.hstack([modal, res])


def modal_constants(freq, frf, poles, *, w_ref: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residues of given poles in all FRFs by linear least squares (LSFD), with residual terms.

    Parameters
    ----------
    freq : float (n_freq,), Hz (no 0 Hz line)
    frf : complex (n_points, n_freq)
    poles : complex (n_modes,), rad/s, positive imaginary parts
    w_ref : rad/s scaling of the residual terms (default: top of the axis)

    Returns
    -------
    A : complex (n_points, n_modes), residues
    residual : float (n_points, len(RESIDUAL_POWERS)), coefficients of (s/w_ref)^k
    synth : complex (n_points, n_freq), the fitted FRFs
    """
    freq = np.asarray(freq, dtype=float)
    frf = np.atleast_2d(np.asarray(frf))
    poles = np.asarray(poles, dtype=complex).reshape(-1)
    w_ref = 2 * np.pi * freq[-1] if w_ref is None else w_ref
    with np.errstate(all="ignore"):
        B = lsfd_basis(freq, poles, w_ref)
        Br = np.vstack([B.real, B.imag])
        norm = np.linalg.norm(Br, axis=0)
        norm[norm == 0] = 1.0
        Y = np.hstack([frf.real, frf.imag]).T                   # (2 nf, n_points)
        X, *_ = np.linalg.lstsq(Br / norm, Y, rcond=1e-12)
        X = (X / norm[:, None]).T                                # (n_points, n_cols)
        n = poles.size
        A = X[:, 0:2 * n:2] + 1j * X[:, 1:2 * n:2]
        synth = X @ B.T
    return A, X[:, 2 * n:], synth


#: false-alarm probability of the significance test of the poles (:func:`pole_false_alarm`):
#: the chance (at most; a Bonferroni bound) that noise alone, with no mode in the lines fitted,
#: gives a pole that passes it anywhere in them
FALSE_ALARM = 0.01


def pole_false_alarm(freq, frf, poles, n_test: int, *, w_ref: float, n_places: int | None = None):
    """Whether each of the first ``n_test`` ``poles`` (rad/s) is more than noise: the false-alarm
    probability of its LSFD columns in the FRFs ``frf`` (n_points, n_freq) on ``freq`` (Hz).

    The extra-sum-of-squares test of nested linear least squares (Seber & Lee, "Linear
    regression analysis", 2nd ed., 2003, section 4.3): with the poles fixed, adding a pole's
    two real columns (Re A, Im A of its residue) to the LSFD model of each FRF lowers its
    residual sum of squares, in units of the noise variance, by a chi-squared variable of 2
    degrees of freedom when the pole is no mode (residue 0), independently in each FRF; summed
    over the n_points FRFs, chi-squared of ``2 n_points``. The noise variance of each line is
    modelled as ``a_p + b_p |H_fit|^2`` (additive noise and noise proportional to the FRF, as
    an H1 estimate's coherence-limited noise; Bendat & Piersol, "Random data", 4th ed., 9.2.4),
    ``a_p, b_p >= 0`` of each FRF from its residuals (each line's squared residual over
    ``1 - leverage``); the test is that of the fit weighted by its inverse (generalised least
    squares). The pole's frequency was not fixed in advance but found where the data fit best:
    the probability is that at one frequency times ``n_places``, the number of lines it could
    have been found at (default: those of ``freq``; :func:`find_modes` gives the lines of all
    its bands, so that the bound holds for the whole fit, not band by band: with one FRF of
    pure noise and ~19 automatic bands, 3 of 200 fits kept a pole of probability 0.003-0.007
    in its band's 27-34 lines). Bonferroni over the places a noise pole could be: a pole
    narrower than the line spacing fits one line's noise; a wider one fewer independent places.
    A pole whose false-alarm probability exceeds :data:`FALSE_ALARM` is no credible mode: its
    contribution is what noise gives somewhere in this many lines. It replaces nothing of the
    ``min_snr`` rule, which compares the pole's peak |A| / sigma, between the lines where the
    pole is narrower than their spacing, with the residual, and so let through a noise pole
    whose peak between two lines was high while at the lines it fitted one line's noise.

    Returns (false-alarm probability (n_test,), statistic (n_test,), its degrees of freedom).
    """
    from scipy.special import chdtrc

    freq = np.asarray(freq, dtype=float)
    frf = np.atleast_2d(np.asarray(frf))
    poles = np.asarray(poles, dtype=complex).reshape(-1)
    n_p, nf = frf.shape
    with np.errstate(all="ignore"):
        B = lsfd_basis(freq, poles, w_ref)
        Br = np.vstack([B.real, B.imag])
        norm = np.linalg.norm(Br, axis=0)
        norm[norm == 0] = 1.0
        Br = Br / norm
        scale = float(np.sqrt(np.mean(np.abs(frf) ** 2))) or 1.0
        Y = np.hstack([frf.real, frf.imag]).T / scale                   # (2 nf, n_p)
        Q = np.linalg.qr(Br)[0]
        fitted = Q @ (Q.T @ Y)
        E = Y - fitted
        lev = np.sum(Q ** 2, axis=1)
        lev = 0.5 * (lev[:nf] + lev[nf:])                               # per line
        fit_c = (fitted[:nf] + 1j * fitted[nf:]).T                      # (n_p, nf)
        e2 = (np.abs(E[:nf]) ** 2 + np.abs(E[nf:]) ** 2).T              # (n_p, nf)
        ok = lev < 0.5
        v = e2[:, ok] / (2 * (1 - lev[ok]))                             # per real component
        x = np.abs(fit_c[:, ok]) ** 2
        a, b = _variance_model(v, x)
        floor = (1e-13 * float(np.max(np.abs(Y)))) ** 2
        var = a[:, None] + b[:, None] * np.abs(fit_c) ** 2 + floor      # (n_p, nf)
        w = 1.0 / np.sqrt(np.concatenate([var, var], axis=1))          # (n_p, 2 nf)
        Qw, Rw = np.linalg.qr(w[:, :, None] * Br[None, :, :])        # (n_p, 2 nf, ncol)
        x = np.linalg.solve(Rw, np.matmul(Qw.transpose(0, 2, 1), (Y.T * w)[:, :, None]))
        # the extra sum of squares of a pole's two columns is the Wald form x_b^T C_bb^-1 x_b
        # of their coefficients and the block of C = (R^T R)^-1 (Seber & Lee, 3.7 and 4.3)
        Ri = np.linalg.inv(Rw)
        k = np.arange(n_test)
        rows = np.stack([2 * k, 2 * k + 1], axis=1)                     # (n_test, 2)
        Rib = Ri[:, rows, :]                                            # (n_p, n_test, 2, ncol)
        Cbb = np.matmul(Rib, Rib.transpose(0, 1, 3, 2))                 # (n_p, n_test, 2, 2)
        xb = x[:, rows, 0][..., None]                                   # (n_p, n_test, 2, 1)
        quad = np.matmul(xb.transpose(0, 1, 3, 2), np.linalg.solve(Cbb, xb))[..., 0, 0]
        stat = np.sum(quad, axis=0)
    dof = 2 * n_p
    p = chdtrc(dof, stat)
    return np.minimum((nf if n_places is None else n_places) * p, 1.0), stat, dof


#: iterations of the reweighted fit of the noise variance model (:func:`_variance_model`)
VARIANCE_ITERATIONS = 4


def _variance_model(v, x):
    """The noise variance model ``v ~ a + b x`` of each row of v and x (n, m), ``a, b >= 0``.

    ``v`` are squared residuals (exponentially distributed about their mean for complex
    Gaussian noise, their spread proportional to it): the fit is iteratively reweighted least
    squares with weights ``1 / (a + b x)^2`` (the likelihood of a gamma model, McCullagh &
    Nelder, "Generalized linear models", 2nd ed., 1989, 8.3), started from the unweighted fit;
    unweighted, the few large residuals at a resonance set the constant ``a``, and noise
    proportional to the FRF was taken about twice too large away from it (a pole's statistic
    averaged 1.8 on 4 degrees of freedom: weak modes there dropped). Where one coefficient
    comes out negative the other is fitted alone. Returns a, b (n,)."""
    wt = np.ones_like(v)
    for _ in range(VARIANCE_ITERATIONS + 1):
        s0, s1, s2 = wt.sum(axis=1), (wt * x).sum(axis=1), (wt * x * x).sum(axis=1)
        t0, t1 = (wt * v).sum(axis=1), (wt * x * v).sum(axis=1)
        det = s0 * s2 - s1 * s1
        ok = det > 1e-12 * s0 * s2
        a = np.divide(s2 * t0 - s1 * t1, det, out=t0 / s0, where=ok)
        b = np.divide(s0 * t1 - s1 * t0, det, out=np.zeros_like(det), where=ok)
        a_alone = t0 / s0
        b_alone = np.divide(t1, s2, out=np.zeros_like(s2), where=s2 > 0)
        a, b = (np.where(a < 0, 0.0, np.where(b < 0, a_alone, a)),
                np.where(a < 0, b_alone, np.where(b < 0, 0.0, b)))
        mu = a[:, None] + b[:, None] * x
        tiny = 1e-300 + 1e-12 * np.max(mu, axis=1, keepdims=True)
        wt = 1.0 / np.maximum(mu, tiny) ** 2
    return np.maximum(a, 0.0), np.maximum(b, 0.0)


def refine_poles(freq, frf, cands, fixed_poles=(), *, w_ref: float, max_damping: float = 0.1):
    """Output-error refinement of the poles of one band (variable projection).

    Minimises ``sum_p ||H_p - B(lam) X_p||^2`` over the natural frequencies and damping ratios
    of ``cands``, the modal constants and residual terms ``X_p`` being eliminated by linear least
    squares at every step (Golub & Pereyra's variable projection; the LSFD model of
    :func:`lsfd_basis`). ``fixed_poles`` (neighbouring bands' modes) stay as they are. Started
    from the stabilised RFP poles this is the maximum-likelihood estimate for white noise; a
    pole whose optimum lies beyond :data:`REFINE_LIMITS` of its start (2 f zeta, damping e^1.5
    times) keeps its start here (:func:`find_modes` drops it: not a credible mode). The answer is the optimum whatever the start (to ~1e-11 of a frequency):
    the projection is computed by QR, the fixed columns projected out once, and Gauss-Newton
    steps end the search (:func:`_gauss_newton_polish`).
    """
    return _refine(freq, frf, cands, fixed_poles, w_ref=w_ref, max_damping=max_damping)[0]


#: bounds of the output-error refinement around its start: frequency +- this many half-power
#: half-widths (f zeta, at least a quarter of a line spacing), damping ratio times e^+-this
REFINE_LIMITS = (2.0, 1.5)


def _refine(freq, frf, cands, fixed_poles=(), *, w_ref: float, max_damping: float = 0.1):
    """:func:`refine_poles`, with per pole whether its optimum lies out of reach: on a bound
    of :data:`REFINE_LIMITS` or with a damping ratio above ``max_damping`` (that pole is
    returned as it came). Returns (poles, out_of_reach bool array)."""
    from dataclasses import replace

    from scipy.optimize import least_squares

    f0 = np.array([c.freq_hz for c in cands])
    z0 = np.array([c.damping_ratio for c in cands])
    fixed = np.asarray(fixed_poles, dtype=complex).reshape(-1)
    Y = np.hstack([frf.real, frf.imag]).T                                  # (2 nf, n_p)
    scale = float(np.sqrt(np.mean(Y ** 2))) or 1.0
    Y = Y / scale
    bw = np.maximum(f0 * z0, 0.25 * float(freq[1] - freq[0]))              # half-power half-width

    def real_columns(B):
        Br = np.vstack([B.real, B.imag])
        return Br / (np.linalg.norm(Br, axis=0) + 1e-300)

    # the columns that do not move (residual terms, neighbours' poles) projected out once: the
    # residual terms are nearly collinear (condition ~1e8 in a band of 1000-1600 Hz), and a
    # projection recomputed at every step carried rounding errors of ~eps x condition that
    # made the cost ragged at the scale of the finite-difference steps, so the optimiser
    # stopped short of the optimum, where its start decided
    B = lsfd_basis(freq, fixed, w_ref)
    Qf = np.linalg.qr(real_columns(B))[0]

    def out_of_fixed(A):
        for _ in range(2):                         # twice: orthogonal to working precision
            A = A - Qf @ (Qf.T @ A)
        return A

    Yf = out_of_fixed(Y)

    def resid(u):
        fr = f0 + u[0::2] * bw
        zr = z0 * np.exp(u[1::2])
        B = lsfd_basis(freq, _pole(fr, zr), w_ref)[:, :2 * fr.size]
        Q = np.linalg.qr(out_of_fixed(real_columns(B)))[0]
        return (Yf - Q @ (Q.T @ Yf)).ravel()

    u0 = np.zeros(2 * f0.size)
    lim = np.tile(REFINE_LIMITS, f0.size)
    kept = (list(cands), np.zeros(len(cands), bool))
    with np.errstate(all="ignore"):
        # started at an optimum already (find_modes' second pass, the neighbours refined),
        # Gauss-Newton alone ends there; otherwise the trust region searches first
        x, done = _gauss_newton_polish(resid, u0, lim)
    if not done:
        try:
            with np.errstate(all="ignore"):
                sol = least_squares(resid, u0, bounds=(-lim, lim), method="trf", x_scale=1.0,
                                    max_nfev=30 * (u0.size + 1), xtol=1e-10, ftol=1e-12)
        except (ValueError, np.linalg.LinAlgError) as exc:  # pragma: no cover - keep RFP values
            log.info("pole refinement failed (%s); keeping the RFP poles", exc)
            return kept
        x = sol.x
        if np.all(np.isfinite(x)) and np.all(np.abs(x) < lim):
            with np.errstate(all="ignore"):
                polished = _gauss_newton_polish(resid, x, lim)[0]
                r_p = resid(polished)
            # a polish, not a search: kept where it does not raise the cost beyond rounding
            if float(r_p @ r_p) <= 2 * sol.cost * (1 + 1e-9):
                x = polished
    r_x, r_0 = resid(x), resid(u0)
    if not np.all(np.isfinite(x)) or float(r_x @ r_x) > float(r_0 @ r_0) + 1e-300:
        return kept       # no better than the start (an exact start: noise-free FRFs)
    out, off = [], np.zeros(len(cands), bool)
    for r, c in enumerate(cands):
        fr, zr = f0[r] + x[2 * r] * bw[r], z0[r] * np.exp(x[2 * r + 1])
        at_bound = (np.isclose(abs(x[2 * r]), lim[0])
                    or np.isclose(abs(x[2 * r + 1]), lim[1]))
        if at_bound or not (0 < zr <= max_damping):
            out.append(c)
            off[r] = True
        else:
            out.append(replace(c, freq_hz=float(fr), damping_ratio=float(zr)))
    return out, off


#: Gauss-Newton steps after the trust-region search of :func:`refine_poles`, and the central
#: difference step of their Jacobian (in half-power bandwidths, the refinement's unit)
POLISH_STEPS = 4
POLISH_DIFF_STEP = 1e-5
#: largest Gauss-Newton step taken (half-power bandwidths): the trust region's answer is within
#: 1e-5 of the optimum; a longer step means it was not near one, and it is kept as it is
POLISH_MAX_STEP = 0.01
#: a step this short (half-power bandwidths; 1e-12 of a frequency at 1 % damping) ends it
POLISH_DONE = 1e-10


def _gauss_newton_polish(resid, x, lim):
    """A few Gauss-Newton steps ``J dx = -r`` from the trust-region search's answer ``x``.

    The trust region accepts a step by the fall of the cost; where a pole is weakly determined
    (a mode 50 times weaker than its neighbours) that fall is below the cost's rounding before
    the optimum is reached, and the search stopped 1e-6 bandwidths short of it, at a place its
    start decided. Gauss-Newton steps go to the stationary point ``J^T r = 0`` without comparing
    costs, so the answer no longer depends on the start. Stops where a step would leave the
    bounds ``lim`` or be longer than :data:`POLISH_MAX_STEP` (not near an optimum: the
    point reached is kept), or after one shorter than :data:`POLISH_DONE`. Returns the point
    and whether it ended so (at the stationary point).
    """
    h = POLISH_DIFF_STEP
    for _ in range(POLISH_STEPS):
        r = resid(x)
        J = np.empty((r.size, x.size))
        for k in range(x.size):
            e = np.zeros(x.size)
            e[k] = h
            J[:, k] = (resid(x + e) - resid(x - e)) / (2 * h)
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        if (not np.all(np.isfinite(step)) or np.any(np.abs(x + step) >= lim)
                or np.max(np.abs(step)) > POLISH_MAX_STEP):
            break
        x = x + step
        if np.max(np.abs(step)) <= POLISH_DONE:
            return x, True
    return x, False


# --------------------------------------------------------------------------- bands
def auto_bands(freq, frf, *, max_peaks: int = 4, prominence_db: float = 6.0
               ) -> list[tuple[tuple[float, float], tuple[float, float], int]]:
    """Bands around the peaks of the summed FRF magnitude.

    Peaks of ``20 log10(sum_p |H_p|)`` with at least ``prominence_db`` prominence are grouped by
    ``max_peaks``; bands are split at the deepest minimum between groups. Each band is fitted
    over its core plus an overlap reaching half-way to the neighbouring band's nearest peak, so
    a mode near a split point (e.g. a weak mode the peak search missed) is inside a fit range.

    Returns
    -------
    list of ((lo, hi) core Hz, (lo, hi) fit range Hz, number of peaks in the fit range)
    """
    from scipy.signal import find_peaks

    freq, frf = _check_arrays(freq, frf)
    db = summed_db(frf)
    peaks, _ = find_peaks(db, prominence=prominence_db)
    peaks = peaks[freq[peaks] > 0]
    if peaks.size == 0:
        raise FrfError("no resonance peak found in the summed FRF magnitude "
                       f"({freq[0]:g}-{freq[-1]:g} Hz); give the bands with --band LO:HI")
    # outer edges: the lowest magnitude between half the first peak and the peak, likewise above
    i0 = np.searchsorted(freq, 0.5 * freq[peaks[0]])
    lo = i0 + int(np.argmin(db[i0:peaks[0] + 1]))
    i1 = min(np.searchsorted(freq, 1.5 * freq[peaks[-1]]), freq.size - 1)
    hi = peaks[-1] + int(np.argmin(db[peaks[-1]:i1 + 1]))
    lo = min(lo, max(peaks[0] - 5, 0))
    hi = max(hi, min(peaks[-1] + 5, freq.size - 1))
    groups = [peaks[i:i + max_peaks] for i in range(0, peaks.size, max_peaks)]
    splits = [lo]
    for a, b in zip(groups[:-1], groups[1:]):
        splits.append(a[-1] + int(np.argmin(db[a[-1]:b[0] + 1])))
    splits.append(hi)
    out = []
    for k, g in enumerate(groups):
        c_lo, c_hi = splits[k], splits[k + 1]
        f_lo = c_lo if k == 0 else (c_lo + groups[k - 1][-1]) // 2
        f_hi = c_hi if k == len(groups) - 1 else (c_hi + groups[k + 1][0]) // 2
        n_pk = int(((peaks >= f_lo) & (peaks <= f_hi)).sum())
        out.append(((float(freq[c_lo]), float(freq[c_hi])), (float(freq[f_lo]), float(freq[f_hi])),
                    n_pk))
    return out


def summed_db(frf) -> np.ndarray:
    """``20 log10(sum_p |H_p|)`` of FRFs ``frf`` (n_points, n_freq): the summed magnitude
    whose peaks place the bands (:func:`auto_bands`) and the notes on peaks without a mode
    (:func:`missed_peak_notes`)."""
    with np.errstate(divide="ignore"):
        return 20 * np.log10(np.abs(np.atleast_2d(frf)).sum(axis=0) + 1e-300)


def _count_peaks(freq, frf, band, prominence_db=6.0) -> int:
    from scipy.signal import find_peaks

    sel = (freq >= band[0]) & (freq <= band[1])
    return int(find_peaks(summed_db(frf[:, sel]), prominence=prominence_db)[0].size)


# --------------------------------------------------------------------------- the whole chain
#: peak bytes of a stabilisation sweep per (FRF x band line x polynomial column): the
#: weighted basis, its [Re; Im] stacking and the per-FRF QR (measured 55-93, see
#: :func:`rfp_memory_bytes`)
RFP_BYTES_PER_VALUE = 112


def rfp_memory_bytes(n_points: int, n_lines: int, n_max: int, n_extra: int) -> float:
    """Estimated peak memory (bytes) of the stabilisation sweep of one band.

    The matrices of :class:`_BandSystem` hold n_points x n_lines x (2 n_max + n_extra) values
    several times over (complex products, [Re; Im] stacking, QR factors); peak resident memory
    measured for 1-10 FRFs of 2e4-1e5 lines is 55-93 bytes per value, so 112 is used.
    """
    return 50e6 + RFP_BYTES_PER_VALUE * n_points * n_lines * (2 * n_max + max(n_extra, 1))


def check_fit_memory(freq, frf, sweeps, n_extra: int, available: float | None = None) -> None:
    """Raise :class:`FrfError` when a band's sweep would need more memory than is available,
    with the estimate; ``sweeps`` is a list of ((lo, hi) Hz, n_max)."""
    from laminid_cli import memory

    available = memory.available_memory_bytes() if available is None else available
    if available is None:
        return
    for (lo, hi), n_max in sweeps:
        n_lines = int(((freq >= lo) & (freq <= hi) & (freq > 0)).sum())
        need = rfp_memory_bytes(frf.shape[0], n_lines, n_max, n_extra)
        if need > available:
            raise FrfError(
                f"fitting band {lo:g}:{hi:g} Hz ({frf.shape[0]} FRFs x {n_lines} lines, up to "
                f"{n_max} modes) needs about {memory.format_bytes(need)} of memory, and "
                f"{memory.format_bytes(available)} is available; fit narrower bands (--band "
                "LO:HI), fewer FRFs, or decimate the lines")


def find_modes(freq, frf, *, bands=None, n_modes: int | None = None,
               criteria: PoleCriteria = PoleCriteria(), source: str = "") -> ModalFit:
    """Natural frequencies, damping and modal constants of all FRFs (global RFP + LSFD).

    Parameters
    ----------
    freq : float (n_freq,), Hz, strictly increasing
    frf : complex (n_points, n_freq)
    bands : list of (lo, hi) Hz; default :func:`auto_bands`. A band with more than
        :data:`MAX_PEAKS_PER_BAND` peaks is fitted as overlapping sub-bands.
    n_modes : return only the ``n_modes`` lowest modes; :class:`FrfError` when fewer are found
    criteria : :class:`PoleCriteria`
    source : the FRF file, named at the start of every :class:`FrfError` message

    Returns
    -------
    ModalFit

    Steps: (1) per band, a stabilisation sweep over N = 1..N_max (N_max = 2 n_peaks + 6, at
    least 8, or ``criteria.max_modes``; capped by the lines of the band) and the physical poles
    of :func:`select_poles`; (2) a pole found by two overlapping bands is kept from the band in
    which it lies farther from the edges; (3) per band, the poles refined by
    :func:`refine_poles` (the neighbouring bands' poles fixed: at their stabilised values, then,
    in a second pass, at their refined ones) and modal constants by :func:`modal_constants`
    with every retained pole near the band (neighbours' poles explicit, not left to residual
    terms); a pole whose refinement would leave its bounds (:data:`REFINE_LIMITS`), or whose
    peak contribution does not exceed ``min_snr`` times the local RMS residual (noise pole), or
    whose modal constants lower the residual no more than noise does somewhere in the lines
    fitted
    (:func:`pole_false_alarm`, false-alarm probability above :data:`FALSE_ALARM`), is
    dropped, the band refitted without it, and it is no other band's neighbour (another pass
    follows one that dropped a pole or moved one by more than :data:`PASS_MOVED`); (4) two
    refined poles within :data:`SAME_MODE_BANDWIDTHS` half-power bandwidths of each other
    are one mode (:func:`_one_mode_twice`): one is dropped and the bands fitted again.
    """
    where = f"{source}: " if source else ""
    try:
        return _find_modes(freq, frf, bands, n_modes, criteria)
    except FrfError as exc:
        if not where or str(exc).startswith(where):
            raise
        raise FrfError(f"{where}{exc}") from exc
    except np.linalg.LinAlgError as exc:   # data the preconditions let through, still degenerate
        raise FrfError(f"{where}the RFP fit failed numerically ({exc}); the FRF data are "
                       "degenerate (check the frequency axis and the FRF values)") from exc


def _find_modes(freq, frf, bands, n_modes, criteria) -> ModalFit:
    freq, frf = _check_arrays(freq, frf)
    if n_modes is not None and n_modes < 1:
        raise FrfError(f"--modes must be at least 1 (got {n_modes})")
    if bands is None:
        plan = _merge_narrow([(rng, n_pk) for _core, rng, n_pk in auto_bands(freq, frf)],
                             freq, frf.shape[0], criteria)
    else:
        plan = []
        for b in bands:
            lo, hi = float(b[0]), float(b[1])
            if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
                raise FrfError(f"band {lo:g}:{hi:g} Hz is empty (upper edge must exceed the lower)")
            if hi < freq[0] or lo > freq[-1]:
                raise FrfError(f"band {lo:g}:{hi:g} Hz lies outside the FRF axis "
                               f"({freq[0]:g}-{freq[-1]:g} Hz)")
            n_pk = _count_peaks(freq, frf, (lo, hi))
            if n_pk <= MAX_PEAKS_PER_BAND:
                plan.append(((lo, hi), n_pk))
                continue
            # many resonances: overlapping sub-bands (one high-order fit over a wide band lets
            # the |D| weighting of the linearised equations vary over decades)
            sel = (freq >= lo) & (freq <= hi)
            sub = auto_bands(freq[sel], frf[:, sel])
            # sub-bands too narrow for a sweep joined to a neighbour, as automatic bands are
            # (noise peaks made one of 8 lines, 293:300 of --band 100:300, and the fit stopped:
            # 'band 293:300 Hz ... too narrow ...; widen it', a band the user never gave)
            plan.extend(_merge_narrow(
                [((lo if k == 0 else s_lo, hi if k == len(sub) - 1 else s_hi), s_pk)
                 for k, (_core, (s_lo, s_hi), s_pk) in enumerate(sub)],
                freq, frf.shape[0], criteria))
    n_p = frf.shape[0]
    sweeps = []
    for rng, n_pk in plan:
        n_lines = int(((freq >= rng[0]) & (freq <= rng[1]) & (freq > 0)).sum())
        _check_band(freq, rng, 1, criteria.n_extra, n_p)
        n_max = criteria.max_modes or max(2 * n_pk + 8, 12)
        if n_modes is not None and bands is not None:
            n_max = max(n_max, n_modes + 6)
        # keep the linearised system overdetermined, by the rule the sweep's fits check (the
        # cap was one mode above it for 2 FRFs: an automatic band of 18 lines was refused,
        # "too few for 11 modes ... ask fewer modes", of a user who asked for none)
        n_cap = max_band_modes(n_lines, criteria.n_extra, n_p)
        if n_modes is not None and bands is not None and len(plan) == 1 and n_modes > n_cap:
            raise FrfError(f"band {rng[0]:g}:{rng[1]:g} Hz holds {n_lines} lines, too few to "
                           f"fit {n_modes} modes; widen the band or ask fewer modes")
        n_max = min(n_max, n_cap)
        if n_max < criteria.min_stable + 1:
            raise FrfError(f"band {rng[0]:g}:{rng[1]:g} Hz holds {n_lines} lines, too narrow "
                           f"for a stabilisation sweep over {criteria.min_stable + 1} orders; "
                           "widen it")
        sweeps.append((rng, n_max))
    check_fit_memory(freq, frf, sweeps, criteria.n_extra)
    margin = EDGE_LINES * float(np.median(np.diff(freq)))
    # the lines of all bands: the places a noise pole could be found (pole_false_alarm)
    covered = np.zeros(freq.size, bool)
    for (lo, hi), _ in sweeps:
        covered |= (freq >= lo) & (freq <= hi) & (freq > 0)
    n_places = int(covered.sum())

    def sweep(ref=None):
        charts, cands = [], []
        for k, (rng, n_max) in enumerate(sweeps):
            ref_k = None
            if ref is not None:
                ref_k = [c for c in ref if rng[0] <= c.freq_hz <= rng[1]]
                ref_k = _pole([c.freq_hz for c in ref_k], [c.damping_ratio for c in ref_k])
            chart = stabilisation(freq, frf, rng, range(1, n_max + 1), criteria=criteria,
                                  ref_poles=ref_k)
            charts.append(chart)
            lo, hi = chart.band_hz
            for c in select_poles(chart, criteria=criteria):
                if lo + margin <= c.freq_hz <= hi - margin:
                    cands.append((k, c, min(c.freq_hz - lo, hi - c.freq_hz) / (hi - lo)))
        return charts, _dedupe(cands, criteria)

    charts, cands = sweep()
    if criteria.reweight and cands:
        # second pass weighted with the first pass's physical poles (Sanathanan-Koerner)
        charts, cands = sweep([c for _, c, _ in cands])

    dead = set()          # indices into cands of poles found to be no modes, or one twice
    twins = {}            # of those, the ones found twice: DroppedPole

    def passes(cands):
        # a band's neighbours (other bands' poles) are fixed in its refinement: at their
        # stabilised RFP values, then, in a second pass, at their refined ones, so that no
        # band's answer follows another band's RFP median (which jumps where a pole's stability
        # flag flips): moved by 0.1 bandwidths, they moved the other bands' frequencies by up
        # to 4e-7 (relative) after one pass, 1e-11 after two (damping 2e-5, 4e-9). A pole a
        # band drops is no neighbour in the next pass, nor a candidate; a pass that dropped one
        # (the bands fitted before it held it fixed), or moved a pole by more than PASS_MOVED,
        # is followed by another
        start = [c for _, c, _ in cands]
        alive = [i not in dead for i in range(len(cands))]
        reach = set()
        gone = {}             # indices into cands of the poles dropped: DroppedPole
        for n_pass in range(MAX_PASSES):
            band_fits, modes, owner, refined = [], [], [], list(start)
            neighbours = dropped = False
            for k, chart in enumerate(charts):
                lo, hi = chart.band_hz
                mine = [i for i, (b, _, _) in enumerate(cands) if b == k and alive[i]]
                near = [start[i] for i, (b, c, _) in enumerate(cands)
                        if b != k and alive[i] and lo - (hi - lo) <= c.freq_hz <= hi + (hi - lo)]
                neighbours = neighbours or bool(near)
                bf, ms, ref = _band_constants(freq, frf, chart, [start[i] for i in mine], near,
                                              criteria, n_places)
                for i, r in zip(mine, ref):
                    if isinstance(r, DroppedPole):    # dropped: "reach", "noise", "chance"
                        alive[i], dropped = False, True
                        gone[i] = r
                        if r.reason == "reach":
                            reach.add(cands[i][1].freq_hz)
                    else:
                        refined[i] = r
                        owner.append(i)
                band_fits.append(bf)
                modes.extend(ms)
            moved = max((abs(refined[i].freq_hz - start[i].freq_hz)
                         / (2 * start[i].freq_hz * start[i].damping_ratio) for i in owner),
                        default=0.0)
            start = refined
            if not (neighbours and (dropped or (criteria.refine
                                                and (n_pass == 0 or moved > PASS_MOVED)))):
                break
        return band_fits, modes, owner, reach, gone

    def constants(cands):
        while True:
            band_fits, modes, owner, reach, gone = passes(cands)
            twin = _one_mode_twice(modes)
            if twin is None:
                gone.update(twins)
                return (band_fits, sorted(modes, key=lambda m: m.freq_hz), reach,
                        sorted(gone.values(), key=lambda d: d.freq_hz))
            a, b, sep = twin
            keep, drop = sorted((a, b), key=lambda r: (-modes[r].orders_stable, -modes[r].snr))
            log.info("poles at %.4f and %.4f Hz are one mode (%.2g half-power bandwidths apart, "
                     "damping %.5f and %.5f): keeping the one at %.3f Hz, refitting",
                     modes[a].freq_hz, modes[b].freq_hz, sep, modes[a].damping_ratio,
                     modes[b].damping_ratio, modes[keep].freq_hz)
            dead.add(owner[drop])
            m = modes[drop]
            twins[owner[drop]] = DroppedPole(
                freq_hz=m.freq_hz, damping_ratio=m.damping_ratio, band_hz=m.band_hz,
                reason="twice", why=(f"{sep:.2g} half-power bandwidths from the pole at "
                                     f"{modes[keep].freq_hz:.3f} Hz: one mode, fitted twice"))

    band_fits, modes, reach, gone = constants(cands)
    if criteria.gap_search:
        found = _new_poles(_gap_search(freq, frf, modes, charts, criteria),
                           [c for _, c, _ in cands], criteria)
        if found:
            log.info("gap search: %d more pole(s) at %s Hz", len(found),
                     ", ".join(f"{c.freq_hz:.2f}" for c in found))
            for c in found:   # into the band where the pole lies farthest from the edges
                k = int(np.argmax([min(c.freq_hz - ch.band_hz[0], ch.band_hz[1] - c.freq_hz)
                                   / (ch.band_hz[1] - ch.band_hz[0]) for ch in charts]))
                cands.append((k, c, 0.0))
            band_fits, modes, reach, gone = constants(cands)
    if n_modes is not None:
        if len(modes) < n_modes:
            where = ", ".join(f"{c.band_hz[0]:g}:{c.band_hz[1]:g}" for c in charts)
            listed = ", ".join(f"{m.freq_hz:.2f}" for m in modes)
            raise FrfError(f"asked for {n_modes} modes but the band(s) {where} Hz hold only "
                           f"{len(modes)} stable modes" + (f" ({listed} Hz)" if modes else "")
                           + "; widen the bands or ask fewer modes")
        modes, beyond = modes[:n_modes], modes[n_modes:]
    else:
        beyond = []
    return ModalFit(modes=tuple(modes), bands=tuple(band_fits), criteria=criteria,
                    beyond=tuple(beyond), out_of_reach=tuple(sorted(reach)),
                    dropped=tuple(gone))


#: most passes over the bands in :func:`find_modes` (two; more after a pass that dropped a
#: pole others held fixed or moved one by more than :data:`PASS_MOVED`)
MAX_PASSES = 4
#: a pass over the bands that moved a pole by more than this many half-power bandwidths (the
#: poles it held fixed in other bands were that far from its answer) is followed by another;
#: a second pass moves them by ~1e-5 (4e-7 of 902 Hz at 1.5 % damping), and the next by 1e-5
#: of that
PASS_MOVED = 1e-4
#: two refined poles closer than this many half-power bandwidths (at equal damping) are one
#: mode: :func:`_one_mode_twice`
SAME_MODE_BANDWIDTHS = 0.1


def pole_overlap(lam_a, lam_b):
    """Cosine of the angle between the modal columns ``1/(s - lam)`` of two poles (rad/s) over
    the whole frequency axis: ``2 sqrt(sa sb) / |sa + sb + j (wa - wb)|`` with ``lam = -s + j w``
    (the integral over w of a product of two resonance curves). 1 for one pole; at equal
    damping ``1 / sqrt(1 + d^2)`` for poles ``d`` half-power bandwidths (2 s) apart; damping
    ratios 1.5 times apart at one frequency give 0.98."""
    sa, sb = -np.real(lam_a), -np.real(lam_b)
    return 2 * np.sqrt(sa * sb) / np.abs(sa + sb + 1j * (np.imag(lam_a) - np.imag(lam_b)))


def _one_mode_twice(modes):
    """(a, b, separation) of the two modes whose poles are nearest to one (their LSFD columns
    collinear: :func:`pole_overlap` at least that of poles :data:`SAME_MODE_BANDWIDTHS` apart),
    separation in half-power bandwidths; ``None`` where no two are.

    Two poles that the output-error refinement brings to one place are one mode, fitted twice
    (two stable tracks of one band's chart, or two bands'): their modal constants are large and
    of opposite sign, and the LSFD's significance test keeps both; listed twice, the mode
    shifted every later mode's index (the emulator's plate at noise 0.2: 497.430 and 497.431
    Hz). Two physical modes at one pole are one in FRFs of one reference too (one pole with the
    sum of their constants fits them exactly). True close modes stay apart: the close pair of
    the tests, 0.75 bandwidths apart, overlaps 0.80."""
    if len(modes) < 2:
        return None
    lam = _pole([m.freq_hz for m in modes], [m.damping_ratio for m in modes])
    cos = pole_overlap(lam[:, None], lam[None, :])
    np.fill_diagonal(cos, 0.0)
    a, b = np.unravel_index(int(np.argmax(cos)), cos.shape)
    if cos[a, b] < 1 / np.sqrt(1 + SAME_MODE_BANDWIDTHS ** 2):
        return None
    sep = abs(lam[a].imag - lam[b].imag) / (-lam[a].real - lam[b].real)
    return int(min(a, b)), int(max(a, b)), float(sep)


def _merge_narrow(plan, freq, n_points: int, criteria) -> list:
    """Automatic bands (``[((lo, hi) Hz, n_peaks)]``) with too few lines for a stabilisation
    sweep over ``min_stable + 1`` orders (:func:`max_band_modes`) joined to their neighbour
    (the lower one where there is one). The peaks of noisy FRFs made a band of 9 lines at the
    axis' end, 1582-1598 Hz, and the fit stopped: 'too narrow ...; widen it', to a user who
    gave no band."""
    plan = list(plan)

    def too_narrow(rng):
        n_lines = int(((freq >= rng[0]) & (freq <= rng[1]) & (freq > 0)).sum())
        return max_band_modes(n_lines, criteria.n_extra, n_points) < criteria.min_stable + 1

    k = 0
    while len(plan) > 1 and k < len(plan):
        if not too_narrow(plan[k][0]):
            k += 1
            continue
        j = k - 1 if k > 0 else k + 1
        (lo_a, hi_a), n_a = plan[min(j, k)]
        (lo_b, hi_b), n_b = plan[max(j, k)]
        plan[min(j, k)] = ((min(lo_a, lo_b), max(hi_a, hi_b)), n_a + n_b)
        del plan[max(j, k)]
        k = max(min(j, k), 0)
    return plan


def _gap_search(freq, frf, modes, charts, criteria) -> list:
    """Stable poles in the gaps between the modes found (weak modes the band fits missed).

    Each gap, from three half-power bandwidths above one mode to three below the next (ends of
    the fitted range included), gets its own narrow fit with Sanathanan-Koerner iterations
    (``sk_iter=2``) over N = 1..8; a weak mode next to strong ones stabilises there where the
    wide band's linearised fit let it wander. The candidates still have to pass the refinement
    and the significance test of :func:`_band_constants`.
    """
    from dataclasses import replace

    crit = replace(criteria, sk_iter=2, reweight=False)
    df = float(np.median(np.diff(freq)))
    lo0 = min(ch.band_hz[0] for ch in charts)
    hi0 = max(ch.band_hz[1] for ch in charts)
    ends = [(lo0, 0.0)] + [(m.freq_hz, m.damping_ratio) for m in modes] + [(hi0, 0.0)]
    out = []
    for (fa, za), (fb, zb) in zip(ends[:-1], ends[1:]):
        lo = fa + 3 * max(za * fa, df)
        hi = fb - 3 * max(zb * fb, df)
        if int(((freq >= lo) & (freq <= hi)).sum()) < 20:
            continue
        try:
            chart = stabilisation(freq, frf, (lo, hi), range(1, 9), criteria=crit)
        except FrfError:  # pragma: no cover - too narrow after all
            continue
        b_lo, b_hi = chart.band_hz
        out.extend(c for c in select_poles(chart, criteria=crit)
                   if b_lo + 2 * df <= c.freq_hz <= b_hi - 2 * df)
    return out


def _new_poles(found, known, criteria) -> list:
    """The gap search's poles that are none of ``known`` (within ``freq_tol``), one per pole.

    A gaps' pole can be a band's candidate that its LSFD dropped as noise (the gaps lie between
    the modes kept), or be found by two tracks of one gap's chart: appended as it was, it sat
    beside its twin, the refinement moved both onto one pole, and the mode was listed twice
    (420.46 Hz twice, from a record windowed with tau = 1 % of it)."""
    out = []
    for c in sorted(found, key=lambda c: -c.orders_stable):
        if any(abs(c.freq_hz - k.freq_hz) < criteria.freq_tol * k.freq_hz
               for k in (*known, *out)):
            continue
        out.append(c)
    return sorted(out, key=lambda c: c.freq_hz)


def _dedupe(cands, criteria):
    """A pole found in two overlapping bands: keep the estimate farther from its band's edges."""
    cands = sorted(cands, key=lambda t: t[1].freq_hz)
    keep = [True] * len(cands)
    for i, (bi, ci, ei) in enumerate(cands):
        for j in range(i + 1, len(cands)):
            bj, cj, ej = cands[j]
            if (cj.freq_hz - ci.freq_hz) / ci.freq_hz >= criteria.freq_tol:
                break
            if bi == bj or not (keep[i] and keep[j]):
                continue
            # same pole seen from two bands (distinct poles of one band are never merged)
            if ei >= ej:
                keep[j] = False
            else:
                keep[i] = False
    return [c for c, k in zip(cands, keep) if k]


def _band_constants(freq, frf, chart, own, near, criteria, n_places: int | None = None):
    """LSFD over one band with its own poles and its neighbours'; drop own poles that are no
    credible modes.

    The own poles are refined (:func:`refine_poles`, the neighbours fixed). A pole whose
    optimum is out of the refinement's reach (:data:`REFINE_LIMITS`: it would move more than
    2 f zeta from its start, or its damping e^1.5 = 4.5 times up or down) is no credible mode:
    it is dropped, with a log line, and the others refined again from their starts without it
    (kept at its start, as it was, it held the reported frequencies at a value its stabilised
    RFP median decided, and sat on a mode the others had found: the emulator's plate at noise
    0.2 listed 497.43 Hz twice, and a spurious 1263.30 Hz with damping 9e-5). Then a pole whose
    peak contribution does not exceed ``min_snr`` times the local residual is dropped (noise
    pole), and the others are refined again and refitted without it; then, likewise, the pole
    whose modal constants are least significant, where its false-alarm probability
    (:func:`pole_false_alarm`, over ``n_places`` lines: those of all bands) exceeds
    :data:`FALSE_ALARM`, one at a time.

    Returns the :class:`BandFit`, its modes and, per pole of ``own``, its refined value or,
    where it was dropped, a :class:`DroppedPole` saying why: "reach" (out of the refinement's
    reach), "noise" or "chance"."""
    lo, hi = chart.band_hz
    sel = (freq >= lo) & (freq <= hi) & (freq > 0)
    f, H = freq[sel], frf[:, sel]
    w_ref = 2 * np.pi * f[-1]
    df = float(f[1] - f[0])
    own = list(own)
    near_poles = _pole([c.freq_hz for c in near], [c.damping_ratio for c in near])

    dropped = {}
    band = (float(lo), float(hi))

    def refine(idx, start):
        """(indices into own, refined poles) of the poles ``idx`` started at ``start``, those
        whose optimum is out of reach dropped"""
        while criteria.refine and idx:
            ref, off = _refine(f, H, start, near_poles, w_ref=w_ref,
                               max_damping=criteria.max_damping)
            if not off.any():
                return idx, ref
            for r in np.flatnonzero(off):
                c = start[r]
                why = (f"its output-error fit would move it more than "
                       f"{REFINE_LIMITS[0] * max(c.freq_hz * c.damping_ratio, 0.25 * df):.3g} Hz "
                       f"or its damping {c.damping_ratio:.5f} {np.exp(REFINE_LIMITS[1]):.1f} "
                       "times (not a credible mode)")
                log.info("dropping pole at %.3f Hz: %s", c.freq_hz, why)
                dropped[idx[r]] = DroppedPole(freq_hz=c.freq_hz, damping_ratio=c.damping_ratio,
                                              band_hz=band, reason="reach", why=why)
            idx = [i for i, o in zip(idx, off) if not o]
            start = [own[i] for i in idx]      # the others again from their starts
        return idx, start

    idx, cur = refine(list(range(len(own))), own)
    fa = np.zeros(0)              # the kept poles' false-alarm probabilities
    while True:
        poles = np.concatenate([_pole([c.freq_hz for c in cur], [c.damping_ratio for c in cur]),
                                near_poles])
        A, res, synth = modal_constants(f, H, poles, w_ref=w_ref)
        resid = np.abs(H - synth)                                           # (n_p, nf)
        snr = np.empty(len(cur))
        for r, c in enumerate(cur):
            # residual RMS within a few half-power bandwidths (at least 5 lines) of the mode
            near_lines = np.abs(f - c.freq_hz) <= max(15 * c.damping_ratio * c.freq_hz, 5 * df)
            noise = np.sqrt(np.mean(resid[:, near_lines] ** 2, axis=1))     # (n_p,)
            peak = np.abs(A[:, r]) / max(-poles[r].real, 1e-300)            # |A| / sigma_r
            floor = 1e-12 * float(np.max(np.abs(H)))
            snr[r] = float(np.max(peak / np.maximum(noise, floor)))
        if not cur:
            break
        if snr.min() >= criteria.min_snr:
            fa, stat, dof = pole_false_alarm(f, H, poles, len(cur), w_ref=w_ref,
                                             n_places=n_places)
            worst = int(np.argmin(stat))          # the least significant (fa is clipped at 1)
            if fa[worst] <= FALSE_ALARM:
                break
            why = (f"its modal constants lower the residual by chi-squared {stat[worst]:.3g} "
                   f"({dof} degrees of freedom), what noise alone gives somewhere in the "
                   f"{n_places or f.size} lines fitted with probability {fa[worst]:.2g} > "
                   f"{FALSE_ALARM:g}")
            reason, p_fa = "chance", float(fa[worst])
        else:
            worst = int(np.argmin(snr))
            why = f"peak/residual {snr[worst]:.2f} < {criteria.min_snr:.2f}"
            reason, p_fa = "noise", None
        c = cur[worst]
        log.info("dropping pole at %.3f Hz: %s", c.freq_hz, why)
        dropped[idx[worst]] = DroppedPole(freq_hz=c.freq_hz, damping_ratio=c.damping_ratio,
                                          band_hz=band, reason=reason, why=why,
                                          false_alarm=p_fa)
        # the others refined again without it (from where they are: near their optimum)
        idx, cur = refine(idx[:worst] + idx[worst + 1:], cur[:worst] + cur[worst + 1:])
    modes = [Mode(freq_hz=c.freq_hz, damping_ratio=c.damping_ratio,
                  modal_constants=A[:, r].copy(), freq_std_hz=c.freq_std_hz,
                  damping_std=c.damping_std, orders_stable=c.orders_stable,
                  band_hz=(float(lo), float(hi)), snr=float(snr[r]),
                  false_alarm=float(fa[r]))
             for r, c in enumerate(cur)]
    bf = BandFit(band_hz=(float(lo), float(hi)), chart=chart, poles=poles, constants=A,
                 residual=res, w_ref=w_ref)
    refined = [dropped.get(i) for i in range(len(own))]
    for i, c in zip(idx, cur):
        refined[i] = c
    return bf, modes, refined


# --------------------------------------------------------------------------- file -> specimen
def measured_from_frf_file(path, *, bands=None, n_modes: int | None = None,
                           criteria: PoleCriteria = PoleCriteria(),
                           with_damping_sigma: bool = False,
                           warnings: list | None = None,
                           damping_sigma_rule: list | None = None) -> tuple:
    """Natural frequencies of the FRFs in a file, for a specimen's ``measured.frf_file``.

    Parameters
    ----------
    path : FRF file (laminid HDF5, UFF 58 or CSV; :func:`laminid_cli.frf.io.read_frf`)
    bands : list of (lo, hi) Hz, default automatic
    n_modes : the n lowest modes (FrfError if fewer found)
    warnings : a list that takes the FRF reader's warnings (a frequency unit not stated);
        without one they are logged
    damping_sigma_rule : a list that takes one line on what set the damping ratios' standard
        deviations (:func:`damping_sigma_summary`: how many are the assumed 2 % floor)

    Returns
    -------
    freq_hz : float (n_modes,), Hz
    sigma_hz : float (n_modes,), Hz, measurement uncertainty (:func:`measurement_sigma`:
        RFP spread, resolution, window, 0.2 % floor)
    damping : float (n_modes,), damping ratios of the structure: with the exponential window
        the file records, its added damping removed (:func:`window_corrected_damping`; NaN
        for a mode whose fitted damping is not above the window's)
    damping_sigma : float (n_modes,), with ``with_damping_sigma``: their standard deviations
        (:func:`damping_sigma`)

    Raises :class:`~laminid_cli.errors.FrfError` on unreadable files or failed fits.
    """
    from laminid_cli.frf.io import read_frf

    fs = read_frf(path)
    for warning in fs.meta.get("warnings") or ():     # each names the file
        if warnings is None:
            log.warning("%s", warning)
        else:
            warnings.append(warning)
    fit = find_modes(fs.freq, fs.frf, bands=bands, n_modes=n_modes, criteria=criteria,
                     source=str(path))
    tau = window_time_constant(fs)
    sig = measurement_sigma(fit, fs.freq, exp_window_s=tau)
    wc = window_corrected_damping(fit, tau)
    if damping_sigma_rule is not None and fit.modes:
        damping_sigma_rule.append(damping_sigma_summary(damping_sigma_dominant(fit)))
    if with_damping_sigma:
        return fit.freq_hz, sig.sigma_hz, wc.damping, wc.sigma
    return fit.freq_hz, sig.sigma_hz, wc.damping


#: floor of a fitted damping ratio's standard deviation, relative to the ratio (2 %)
DAMPING_SIGMA_FLOOR_REL = 0.02


def damping_sigma(fit: ModalFit) -> np.ndarray:
    """Standard deviations of the fitted damping ratios, for the loss-factor identification.

    The spread over the stable orders, floored at :data:`DAMPING_SIGMA_FLOOR_REL` of the
    damping ratio (a noise-free fit has no spread).
    """
    if not fit.modes:
        return np.zeros(0)
    std = np.array([m.damping_std for m in fit.modes])
    return np.maximum(std, DAMPING_SIGMA_FLOOR_REL * fit.damping_ratio)


def damping_sigma_dominant(fit: ModalFit) -> list[str]:
    """Per mode, the term that set :func:`damping_sigma`: "floor" (2 % of the ratio, an
    assumed figure: the orders agreed more closely) or "rfp spread" (the spread over the
    stable orders, measured), as the frequencies' 'from' column names theirs."""
    if not fit.modes:
        return []
    std = np.array([m.damping_std for m in fit.modes])
    floor = DAMPING_SIGMA_FLOOR_REL * np.asarray(fit.damping_ratio, float)
    return ["rfp spread" if s > f else "floor" for s, f in zip(std, floor)]


def damping_sigma_summary(dominant: list[str]) -> str:
    """One line on the damping ratios' standard deviations and what set them (the terminal
    table's 'from' column for zeta, --json's damping_sigma_rule)."""
    n = len(dominant)
    floor = sum(d == "floor" for d in dominant)
    text = (f"fitted ratio's spread over the stable orders, at least "
            f"{100 * DAMPING_SIGMA_FLOOR_REL:g} % of the ratio; dominated by: "
            + ", ".join(f"{d} {c}" for d, c in (("rfp spread", n - floor), ("floor", floor))
                        if c) + " (modes)")
    if floor:
        text += (f"; the floor is an assumed {100 * DAMPING_SIGMA_FLOOR_REL:g} %, not a spread "
                 "the FRFs showed")
    return text


#: Where the exponential window's convention comes from (written beside the code, issue 1 of
#: the frf-fixes branch). The window multiplies the response record by w(t) = exp(-t / tau):
#: the 35670A takes tau in seconds (``[SENSe:]WINDow[1|2|3|4]:EXPonential``: pymeasure's
#: Keysight35670A driver, ``exponential_window_time_constant``, "time constant in seconds"),
#: the SR785 as a percent of the time record (``FWTC``; our driver sends 100 tau / T and
#: records tau in seconds). tau is the time constant of the amplitude (w(tau) = 1/e), the
#: first of the conventions listed by W. Fladung, "Windows used for impact testing", IMAC XV
#: (1997) pp. 1662-1666, section on the exponential window ("specifying the time constant
#: (tau) in seconds"; the other conventions, the reciprocal beta = 1/tau in rad/s or the value
#: reached at the end of the record, are converted to it before they reach the file). By the
#: shift property of the Laplace transform (same paper) a free decay exp(lam t) becomes
#: exp((lam - 1/tau) t): every pole moves left by 1/tau and the fitted decay rate is
#: zeta omega_n + 1/tau, which modal tests remove after the fit ("the added damping is then
#: removed mathematically", Dirac Delta glossary, "Exponential Window"). The emulators of
#: tests/instrument/ and tests/test_window_damping.py (a record windowed sample by sample)
#: check the sign and size.
WINDOW_CONVENTION = ("exponential window w(t) = exp(-t/tau), tau in seconds (amplitude to 1/e "
                     "at tau): fitted decay rate = zeta*omega_n + 1/tau")


@dataclass(frozen=True)
class WindowCorrection:
    """Modal damping with an exponential response window's added damping removed.

    exp_window_s : the window's time constant tau (s), None when the FRF file records none
    fitted : (n,) damping ratios of the fitted poles (with the window's damping in them)
    removed : (n,) what the window added, ``fitted - damping`` (~ 1 / (tau omega_n)); NaN where
        ``damping`` is NaN, 0 without a window
    window : (n,) the window's share ``1 / (tau omega_n)`` at each fitted |pole| (0 without)
    damping : (n,) damping ratios of the structure; NaN where the fitted decay rate is not above
        the window's 1/tau (the FRF does not determine that mode's damping)
    sigma : (n,) their standard deviations (:func:`damping_sigma` of the fit: subtracting the
        exactly known 1/tau leaves the absolute standard deviation as it was); NaN where
        ``damping`` is NaN
    below : indices of the modes whose fitted damping is not above the window's
    """

    exp_window_s: float | None
    fitted: np.ndarray
    removed: np.ndarray
    window: np.ndarray
    damping: np.ndarray
    sigma: np.ndarray
    below: tuple[int, ...]

    def summary(self) -> str:
        """One line: what was removed (empty without a window)."""
        if self.exp_window_s is None or not self.fitted.size:
            return ""
        text = (f"the exponential window's 1/(tau*omega_n) (tau = {self.exp_window_s:g} s, "
                "from the FRF file's settings) removed from each damping ratio")
        ok = np.isfinite(self.removed)
        if ok.any():
            lo, hi = (f"{100 * v:.3g}" for v in (self.removed[ok].min(), self.removed[ok].max()))
            text += f": {lo} % " if lo == hi else f": {hi} to {lo} % "
            text += "(the 'window' column)"
        if self.below:
            text += (f"; mode(s) {', '.join(str(i + 1) for i in self.below)} not above it "
                     "(see the note)")
        return text

    def below_notes(self, freq_hz) -> list[str]:
        """One sentence per mode whose fitted damping is not above the window's."""
        notes = []
        for i in self.below:
            notes.append(
                f"mode {i + 1} ({freq_hz[i]:.2f} Hz): fitted damping {100 * self.fitted[i]:.3g} % "
                f"is not above the window's 1/(tau*omega_n) = {100 * self.window[i]:.3g} % "
                f"(tau = {self.exp_window_s:g} s), which no decaying mode can give: the window "
                "applied was not the one the file records, or this mode's fit is poor. Its "
                "damping is not measured (null in --json and --into)")
        return notes


def window_corrected_damping(fit: ModalFit, exp_window_s: float | None) -> WindowCorrection:
    """Remove an exponential response window's added damping from the fitted modes.

    The window multiplies the free decay by exp(-t/tau) (:data:`WINDOW_CONVENTION`), so each
    fitted pole is the structure's pole moved by -1/tau: ``lam_fit = lam - 1/tau``. The
    structure's pole is ``lam_fit + 1/tau``; its damping ratio ``-Re / |.|``::

        sigma_fit = zeta_fit omega_fit,  omega_d = omega_fit sqrt(1 - zeta_fit^2)
        sigma = sigma_fit - 1/tau,        zeta = sigma / sqrt(omega_d^2 + sigma^2)

    i.e. ``zeta = zeta_fit - 1/(tau omega_n)`` to first order. A mode whose ``sigma`` is not
    positive (fitted decay not above the window's) gets NaN and is listed in ``below``; it is
    never clipped to a small positive number or written negative.

    >>> from types import SimpleNamespace
    >>> w = 2 * np.pi * 100.0                  # 100 Hz, zeta 1 %, tau 0.1 s (1/tau = 10 /s)
    >>> lam = complex(-0.01 * w - 10.0, w * np.sqrt(1 - 0.01**2))     # the windowed pole
    >>> fit = SimpleNamespace(modes=[SimpleNamespace(damping_std=0.0)],
    ...                       freq_hz=np.array([abs(lam) / (2 * np.pi)]),
    ...                       damping_ratio=np.array([-lam.real / abs(lam)]))
    >>> c = window_corrected_damping(fit, 0.1)
    >>> round(float(c.damping[0]), 12), round(float(c.removed[0]), 4)
    (0.01, 0.0159)
    """
    n = len(fit.modes)
    fitted = np.asarray(fit.damping_ratio, float) if n else np.zeros(0)
    sig = damping_sigma(fit) if n else np.zeros(0)
    if exp_window_s is None or not (np.isfinite(exp_window_s) and exp_window_s > 0) or not n:
        z = np.zeros(n)
        return WindowCorrection(None, fitted, z, z.copy(), fitted.copy(), sig, ())
    wn = 2 * np.pi * np.asarray(fit.freq_hz, float)
    wd = wn * np.sqrt(np.clip(1 - fitted**2, 0, None))
    decay = fitted * wn - 1.0 / exp_window_s
    below = decay <= 0
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(below, np.nan, decay / np.hypot(wd, decay))
    return WindowCorrection(
        exp_window_s=float(exp_window_s), fitted=fitted, removed=fitted - zeta,
        window=1.0 / (exp_window_s * wn), damping=zeta, sigma=np.where(below, np.nan, sig),
        below=tuple(int(i) for i in np.flatnonzero(below)))


#: a mode below the window's damping limit is named as possibly missed when that limit is
#: above this fraction of the lowest mode found (a free plate's lowest modes lie within a
#: factor 2-3 of each other, S1.1 125 and 203 Hz: a mode far below the lowest found is not
#: to be expected, one near it is)
WINDOW_LIMIT_NOTE_RATIO = 0.25


def window_damping_limit_hz(exp_window_s: float, max_damping: float) -> float:
    """Frequency (Hz) below which an exponential window of time constant ``exp_window_s`` (s)
    alone adds more than ``max_damping`` to a pole's damping ratio, 1/(tau omega) >
    max_damping: below it no pole passes :class:`PoleCriteria`'s damping rule (0 < zeta <=
    max_damping, applied to the fitted, windowed poles) and no mode can be found."""
    return 1.0 / (2 * np.pi * exp_window_s * max_damping)


#: a peak of the summed FRF magnitude this prominent (dB) with no mode found near it is named
#: in a note (missed_peak_notes): the emulated plate at --noise 0.2 (coherence ~0.8 at its
#: resonances) hid its 212.4 Hz mode, a 21.9 dB peak, from the fit, where noise peaks reached
#: 16.3 dB; a clean mode's peak can be as low as 6.6 dB, so a lower figure would name noise
MISSED_PEAK_DB = 20.0
#: "near": within this fraction of the peak's frequency (or two lines, the larger)
MISSED_PEAK_REL = 0.02


def missed_peak_notes(fit: ModalFit, freq, frf) -> list[str]:
    """Notes on the peaks of the summed FRF magnitude at least MISSED_PEAK_DB prominent,
    inside the bands fitted, with no mode found within MISSED_PEAK_REL of them: a mode the
    fit missed in noisy FRFs (its band gave no stable pole). Unsaid, it went unnoticed, and
    ``--into`` would write the modes above it one place too low, so that identify paired
    every one of them with the wrong model mode."""
    from scipy.signal import find_peaks

    freq = np.asarray(freq, float)
    peaks, props = find_peaks(summed_db(frf), prominence=MISSED_PEAK_DB)
    # (a mode found above the n lowest asked for is no mode missed)
    found = np.concatenate([fit.freq_hz, [m.freq_hz for m in getattr(fit, "beyond", ())]])
    step = float(np.median(np.diff(freq))) if freq.size > 1 else 0.0
    notes = []
    for i, prom in zip(peaks, props["prominences"]):
        f = float(freq[i])
        if f <= 0 or not any(b.band_hz[0] <= f <= b.band_hz[1] for b in fit.bands):
            continue
        if found.size and np.min(np.abs(found - f)) <= max(MISSED_PEAK_REL * f, 2 * step):
            continue
        lo, hi = 0.8 * f, 1.2 * f
        near = f"{MISSED_PEAK_REL * 100:.0f} %"
        notes.append(f"the summed |H| peaks at {f:.1f} Hz ({prom:.0f} dB above its "
                     f"surroundings) and no mode was found within {near} of it: a mode "
                     f"missed in noise? Fit that band alone (--band {lo:.0f}:{hi:.0f}) or "
                     "measure with more averages; with --into, the modes above it would be "
                     "written one place too low")
    return notes


def window_limit_note(fit: ModalFit, freq, exp_window_s: float | None,
                      record_s: float | None = None) -> str | None:
    """A note when the window's damping limit (:func:`window_damping_limit_hz`) lies on the
    FRF axis and close enough under the lowest mode found (:data:`WINDOW_LIMIT_NOTE_RATIO`)
    that a mode there may have been missed: the list would then start with the plate's second
    mode, and identify pair every measured mode with the model mode below it. None otherwise.
    ``record_s``: the time record (lines / span), to suggest a time constant."""
    if exp_window_s is None:
        return None
    f_lim = window_damping_limit_hz(exp_window_s, fit.criteria.max_damping)
    freq = np.asarray(freq, float)
    first = freq[freq > 0]
    if not first.size or f_lim <= first[0]:
        return None
    lowest = float(np.min(fit.freq_hz)) if len(fit.modes) else None
    if lowest is not None and f_lim < WINDOW_LIMIT_NOTE_RATIO * lowest:
        return None
    found = (f"the lowest mode found is at {lowest:.1f} Hz" if lowest is not None
             else "no mode was found")
    advice = "measure again with a longer --exp-window"
    if record_s is not None and np.isfinite(record_s) and record_s > 0:
        advice += f" (a quarter of the time record or more: {record_s / 4:g} s)"
    return (f"below {f_lim:.0f} Hz the exponential window (tau = {exp_window_s:g} s) alone "
            f"adds more than {fit.criteria.max_damping:.0%} damping, the most a mode may "
            f"have: no mode can be found there, and {found}. If the plate has a mode below "
            f"{f_lim:.0f} Hz, this list lacks it, and identify would pair each mode with the "
            f"model mode below it; {advice}")


def window_unknown(fs) -> bool:
    """True when the FRF file's settings name an exponential window but not its time constant
    (``exp_window_s`` NaN or empty: acquired with ``--keep-setup``, which cannot read it)."""
    settings = fs.meta.get("settings") or {}
    return "exp_window_s" in settings and window_time_constant(fs) is None


def window_time_constant(fs) -> float | None:
    """The exponential window's time constant (s) of an FRF set's acquisition settings, if
    recorded (``exp_window_s``, laminid_cli.frf.store)."""
    try:
        value = float((fs.meta.get("settings") or {}).get("exp_window_s"))
    except (TypeError, ValueError):
        return None
    return value if np.isfinite(value) and value > 0 else None


#: default relative floor of a measured frequency's standard deviation (as identify's
#: --sigma-rel): what limits a natural frequency beyond the FRF itself (supports, temperature,
#: transducer mass, repeatability)
DEFAULT_SIGMA_REL = 0.002
#: names of the terms of :func:`measurement_sigma`
SIGMA_TERMS = ("rfp spread", "resolution", "window", "floor")


@dataclass(frozen=True)
class MeasurementSigma:
    """Standard deviation of each fitted natural frequency as a measurement uncertainty.

    sigma_hz : (n_modes,) Hz, ``max(sqrt(spread^2 + resolution^2 + window^2), floor)``
    terms : {name: (n_modes,) Hz} for the names of :data:`SIGMA_TERMS`
    dominant : per mode, the name of the largest term
    sigma_rel : the relative floor used
    """

    sigma_hz: np.ndarray
    terms: dict
    dominant: tuple[str, ...]
    sigma_rel: float

    def summary(self) -> str:
        """One line: the rule and which term dominated how many modes."""
        counts = {t: self.dominant.count(t) for t in SIGMA_TERMS if t in self.dominant}
        dom = ", ".join(f"{t} {n}" for t, n in counts.items())
        return (f"fit-frf: sqrt(RFP spread^2 + resolution^2 + window^2), at least "
                f"{self.sigma_rel * 100:.3g} % of f (--sigma-rel); dominated by: {dom} "
                f"(modes)")


def line_spacing(freq, at) -> np.ndarray:
    """The spacing (Hz) of the frequency lines ``freq`` (increasing) on either side of each
    frequency of ``at``: of the grid interval holding it (of the first or last interval
    outside the grid)."""
    grid = np.asarray(freq, dtype=float)
    at = np.asarray(at, dtype=float)
    k = np.clip(np.searchsorted(grid, at), 1, grid.size - 1)
    return grid[k] - grid[k - 1]


def measurement_sigma(fit: ModalFit, freq, *, sigma_rel: float = DEFAULT_SIGMA_REL,
                      exp_window_s: float | None = None) -> MeasurementSigma:
    """What limits each fitted natural frequency, as a standard deviation (Hz).

    Terms (combined in quadrature as independent standard uncertainties, GUM):

    - RFP spread: the standard deviation of the frequency over the stable model orders (the
      fitter's own precision);
    - resolution: ``df / sqrt(12)``, a uniform distribution over one line spacing ``df`` —
      what the frequency grid can resolve whatever the fit interpolates; ``df`` the spacing
      of the lines on either side of each mode's frequency (an analyser's grid is even, and
      this is its line spacing; another tool's may be uneven, logarithmic: there the median
      spacing would be the wrong width, 10x too small at the top of a decade-spanning grid);
    - window: with an exponential response window of time constant ``tau`` (impact testing,
      ``exp_window_s`` in the FRF file's settings) every pole's decay rate is raised by
      ``1/tau``; the fitted ``f_n = |pole| / 2 pi`` is then above the unwindowed one by
      ``(|pole| - sqrt(omega_d^2 + (zeta omega_n - 1/tau)^2)) / 2 pi`` (0 without a window);

    and the result is floored at ``sigma_rel * f`` (the user's floor: supports, temperature,
    repeatability — what the FRF cannot show). ``dominant`` names the largest term per mode.
    """
    n = len(fit.modes)
    f = fit.freq_hz if n else np.zeros(0)
    spread = np.nan_to_num(np.asarray(fit.freq_std_hz, float)) if n else np.zeros(0)
    resolution = line_spacing(freq, f) / np.sqrt(12.0)
    window = np.zeros(n)
    if exp_window_s is not None and np.isfinite(exp_window_s) and exp_window_s > 0 and n:
        wn = 2 * np.pi * f
        zeta = np.asarray(fit.damping_ratio, float)
        wd = wn * np.sqrt(np.clip(1 - zeta**2, 0, None))
        sig = np.clip(zeta * wn - 1.0 / exp_window_s, 0, None)
        window = np.abs(wn - np.sqrt(wd**2 + sig**2)) / (2 * np.pi)
    floor = sigma_rel * f
    combined = np.sqrt(spread**2 + resolution**2 + window**2)
    sigma = np.maximum(combined, floor)
    terms = {"rfp spread": spread, "resolution": resolution, "window": window, "floor": floor}
    stack = np.vstack([terms[t] for t in SIGMA_TERMS]) if n else np.zeros((4, 0))
    dominant = tuple(SIGMA_TERMS[int(k)] for k in np.argmax(stack, axis=0))
    return MeasurementSigma(sigma_hz=sigma, terms=terms, dominant=dominant,
                            sigma_rel=float(sigma_rel))


def frequency_sigma(fit: ModalFit, freq, **kwargs) -> np.ndarray:
    """Standard deviations (Hz) of the fitted frequencies: :func:`measurement_sigma`."""
    return measurement_sigma(fit, freq, **kwargs).sigma_hz
