r"""Signal-processing blocks of the signal chain, each usable alone on uniformly sampled arrays.

Identification needs ``q̇`` and ``q̈``, which robots rarely log; they are estimated off line from
the measured positions with non-causal filters (Gautier 1997, "Dynamic identification of robots
with power model", ICRA, doi:10.1109/ROBOT.1997.614364; Swevers, Ganseman, Tükel, De Schutter,
Van Brussel 1997, "Optimal robot excitation and identification", IEEE T-RA 13(5),
doi:10.1109/70.631234).

:func:`lowpass`
    zero-phase Butterworth (``scipy.signal.sosfiltfilt``): the forward-backward filter's power
    (squared magnitude) is ``|H(f)|² = 1/(1 + (f/f_c)^{2n})²``, −6 dB in magnitude at ``f_c``;
    no phase lag.
:func:`central_difference`
    ``q̇_k = (q_{k+1} − q_{k−1}) / 2h``, ``q̈_k = (q_{k+1} − 2q_k + q_{k−1}) / h²``.
:func:`savgol_derivatives`
    Savitzky–Golay local polynomial fits (Savitzky & Golay 1964, Anal. Chem. 36(8),
    doi:10.1021/ac60214a047); the window whose −3 dB point is nearest the cut-off, found from
    the filter's frequency response starting at Schafer's rule
    ``f_c ≈ (p + 1) / (3.2 w − 4.6) · f_s`` (Schafer 2011, IEEE Signal Proc. Mag. 28(4),
    doi:10.1109/MSP.2011.941097), which alone puts it at 0.8–0.9 × the cut-off.
:func:`fourier_derivatives`
    for periodic excitations: average the whole periods, keep the harmonics below the cut-off,
    differentiate by multiplying harmonic ``k`` by ``(i k ω_f)`` (Swevers et al. 1997).
:func:`hampel`, :func:`stuck_samples`, :func:`bridge`
    outlier rejection against a running median (Hampel 1974, JASA 69(346),
    doi:10.1080/01621459.1974.10482962) that leaves steps alone; runs of a value repeated by a
    logger while the joint moved; their replacement by interpolation.
:func:`low_speed_mask`
    drop samples where some joint moves slower than a threshold: around velocity reversals the
    Coulomb term switches sign and is badly described (De Luca's lecture notes, the seeds), which
    matters when friction is not modelled.
:func:`estimate_bandwidth`, :func:`default_cutoff`
    the excitation bandwidth from the part of the position spectrum that stands above its
    noise (so that sensor noise, encoder counts and the error of stamps that jitter are not read
    as motion), and the derivative cut-off ``f_d = 10 × bandwidth`` (Gautier's rule of thumb;
    with the few-Hz excitations of the seeds it gives their 30 Hz at 1 kHz), at most 0.4 × the
    sampling rate. A torque is a nonlinear function of the motion, whose harmonics reach past
    the position's band (products of velocities, ``sin``/``cos`` of the angles), and the same
    filter on ``τ`` must not cut what ``Y(q̂) π`` holds: ``Y`` of the filtered positions keeps
    them. At 2–4 × the band that mismatch makes the base parameters of MuJoCo-simulated arms
    10–100 × less accurate than at 10 × (``benchmarks/cutoff.py --factors``). Filtering the
    columns of ``Y`` with the same low-pass as ``τ`` (parallel filtering, Gautier 1997) removes
    it: identification does it, at the identification cut-off ``3 × bandwidth`` that the chain
    records on the dataset (:mod:`consistid.data.parallel`). Here, ``sign(q̇)``, the Coulomb
    column, is filtered like ``τ`` at ``f_d`` (:attr:`~consistid.data.dataset.Dataset.dq_sign`).

The chain that strings them together is :mod:`consistid.data.chain`.
"""

from __future__ import annotations

import functools

from typing import Sequence

import numpy as np
import scipy.ndimage
import scipy.signal

from ..errors import DatasetError, OptionError

#: Derivative cut-off = this × the excitation bandwidth (Gautier's rule of thumb; module
#: docstring). Identification's cut-off is :data:`consistid.data.parallel.PARALLEL_FACTOR` × it.
CUTOFF_FACTOR = 10.0
#: The cut-off never exceeds this fraction of the sampling rate (0.8 × Nyquist).
MAX_CUTOFF_FRACTION = 0.4
#: A periodogram bin of :func:`estimate_bandwidth` counts as motion by its power above this
#: many times the running median of its neighbourhood (the noise's local level): a noise bin
#: (χ²₂, median ``ln 2`` × its mean) passes with probability ``exp(−10 ln 2) ≈ 1e-3``, and
#: what passes keeps ~0.1 % of the noise's power.
NOISE_MARGIN = 10.0
#: Width of that neighbourhood as a fraction of the bins up to the Nyquist frequency (1/64:
#: 7.8 Hz at 1 kHz), wide beside an excitation band of a few Hz, narrow beside coloured noise.
NOISE_WINDOW = 1.0 / 64
#: How far the centred median may raise the looking-up one in :func:`_noise_level`: ``4`` is
#: the ratio of the two medians of ``1/f²`` noise at half a window from zero,
#: ``(1 + w/(2f))²`` at ``f = w/2``, and less beyond; lines of the motion in the centred window
#: (a short log's band fills it) raise it without bound.
CENTRED_GAIN = 4.0
#: :func:`hampel`'s noise level is taken over this many windows around each sample.
HAMPEL_SCALE_WINDOWS = 25
#: The relative rounding step of float32 (``2⁻²³``): :func:`hampel`'s least scale.
FLOAT32_EPS = 2.0 ** -23
#: The third quartile of ``|z|`` for a standard Gaussian ``z`` (``Φ⁻¹(0.875)``).
GAUSS_Q75 = 1.1503493803760079
#: Odd-reflection padding of :func:`lowpass`, in periods of the cut-off.
PAD_PERIODS = 6.0


def real_array(name: str, x: object) -> np.ndarray:
    """``x`` as a float array; :class:`DatasetError` naming ``name`` for complex numbers (numpy
    would drop their imaginary parts with only a ``ComplexWarning``) and for booleans (no joint
    position or torque is true or false)."""
    try:
        a = np.asarray(x)
    except ValueError as exc:                   # ragged rows
        raise DatasetError(f"{name} is not an array of numbers ({exc})") from None
    if a.dtype.kind == "c":
        raise DatasetError(f"{name} holds complex numbers (dtype {a.dtype}); joint signals are "
                           "real: pass their real part (np.real) if the imaginary part is 0")
    if a.dtype.kind == "b":
        raise DatasetError(f"{name} holds booleans, not numbers; pass the logged values")
    if a.dtype.kind in "mM":
        raise DatasetError(f"{name} holds {a.dtype} date-times, whose unit float() drops; pass "
                           "seconds (e.g. (t - t[0]) / np.timedelta64(1, 's'))")
    try:
        return a.astype(float, copy=False)
    except (TypeError, ValueError) as exc:      # text, objects
        raise DatasetError(f"{name} holds {a.dtype.name} values, not numbers ({exc}); pass "
                           "the logged values as numbers") from None


def transposed_hint(shape: tuple[int, ...], n: int) -> str:
    """``"; …transposed…"`` when an array of ``shape`` has the ``n`` samples of ``t`` along its
    second axis — one row per joint instead of one row per sample — else ``""``."""
    if len(shape) == 2 and shape[1] == n and shape[0] != n:
        return (f" (its shape {tuple(shape)} has them along the other axis: transpose it to "
                f"({n}, {shape[0]}), one row per sample)")
    return ""


def as_2d(name: str, x: np.ndarray) -> np.ndarray:
    a = real_array(name, x)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise DatasetError(f"{name} must be (N,) or (N, nv), got shape {a.shape}")
    return a


@functools.lru_cache(maxsize=256)
def _butterworth(order: int, cutoff: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """The second-order sections of a Butterworth low-pass and their steady-state initial
    conditions (``scipy.signal.sosfilt_zi``), made once per (order, f_c, f_s): a diagnosis
    filters the same signals at the same cut-offs hundreds of times.

    Even orders are paired from ``scipy.signal.butter``'s poles directly, as its
    ``zpk2sos(pairing="nearest")`` pairs them (every zero at ``z = −1``: numerators
    ``[1, 2, 1]``, the gain on the first; each conjugate pole pair ``p`` gives
    ``[1, −2 Re p, |p|²]``; sections ordered from the pole pair farthest from the unit circle to
    the nearest): the same numbers bit for bit, ten times faster (its generic pairing is 0.3 ms
    of Python, and a diagnosis tunes cut-offs over a continuum). Odd orders: ``butter`` itself.
    """
    if order % 2:
        sos = scipy.signal.butter(order, cutoff, fs=rate, output="sos")
    else:
        _, poles, gain = scipy.signal.butter(order, cutoff, fs=rate, output="zpk")
        upper = poles[poles.imag > 0]
        upper = upper[np.argsort(-np.abs(1 - np.abs(upper)), kind="stable")]
        sos = np.zeros((order // 2, 6))
        sos[:, :4] = (1.0, 2.0, 1.0, 1.0)
        sos[:, 4] = -2.0 * upper.real
        sos[:, 5] = upper.real * upper.real + upper.imag * upper.imag
        sos[0, :3] *= gain
    zi = _steady_state(sos)
    sos.flags.writeable = zi.flags.writeable = False       # shared between callers
    return sos, zi


def _steady_state(sos: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfilt_zi(sos)`` for sections with ``a₀ = 1``: each section's
    ``(I − Aᵀ) z = b[1:] − a[1:] b₀`` (``A`` the companion matrix of ``a``, as
    ``scipy.signal.lfilter_zi`` writes it) solved by LAPACK for all sections at once, scaled by
    the DC gains ``Σb/Σa`` of the sections before it: the same numbers, a third of the time."""
    b, a = sos[:, :3], sos[:, 3:]
    if not np.all(a[:, 0] == 1.0):
        return scipy.signal.sosfilt_zi(sos)
    system = np.empty((sos.shape[0], 2, 2))
    system[:, 0, 0] = 1.0 + a[:, 1]
    system[:, 0, 1] = -1.0
    system[:, 1, 0] = a[:, 2]
    system[:, 1, 1] = 1.0
    zi = np.linalg.solve(system, (b[:, 1:] - a[:, 1:] * b[:, :1])[..., None])[..., 0]
    scale = 1.0
    for k in range(sos.shape[0]):
        zi[k] = scale * zi[k]
        scale *= np.sum(b[k]) / np.sum(a[k])
    return zi


def _filtfilt(sos: np.ndarray, zi: np.ndarray, x: np.ndarray, pad: int) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0, padlen=pad)`` (``pad ≥ 1``) with its initial
    conditions ``zi = sosfilt_zi(sos)`` made once per design: the same steps (odd extension,
    forward pass from ``zi·x₀``, backward pass from ``zi·y_end``, trim), the same numbers."""
    ext = np.concatenate((2 * x[:1] - x[pad:0:-1], x, 2 * x[-1:] - x[-2:-(pad + 2):-1]),
                         axis=0)
    zi = zi.reshape((zi.shape[0], 2) + (1,) * (x.ndim - 1))
    sos = sos.copy()                                        # scipy wants it writable
    y, _ = scipy.signal.sosfilt(sos, ext, axis=0, zi=zi * ext[:1])
    y, _ = scipy.signal.sosfilt(sos, y[::-1], axis=0, zi=zi * y[-1:])
    return y[::-1][pad:-pad]


def lowpass(x: np.ndarray, cutoff: float, rate: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass along axis 0 (``scipy.signal.sosfiltfilt``).

    ``order`` is that of the one-way filter; run forward and backward, the magnitude is squared
    (``|H|² = 1/(1 + (f/f_c)^{2n})²``, −6 dB at ``f_c``) and the phase is zero. The ends are
    padded by odd reflection over ``6 / f_c`` seconds (scipy's default, 15 samples, leaves the
    initial-state transient in the data: 20× larger edge errors in ``q̈``).
    """
    if not 0 < cutoff < 0.5 * rate:
        raise OptionError(f"cutoff = {cutoff} Hz must lie in (0, {0.5 * rate:g}) Hz, below the "
                          f"Nyquist frequency of {rate:g} Hz sampling")
    sos, zi = _butterworth(order, float(cutoff), float(rate))
    x = np.asarray(x, dtype=float)
    pad = min(int(np.ceil(PAD_PERIODS * rate / cutoff)), x.shape[0] - 1)
    if pad >= 1 and x.ndim <= 2:
        return _filtfilt(sos, zi, x, pad)
    return scipy.signal.sosfiltfilt(sos.copy(), x, axis=0, padlen=pad)  # scipy wants it writable


def lowpass_columns(x: np.ndarray, cutoff: float, rate: float, order: int = 4) -> np.ndarray:
    """:func:`lowpass` of each column of ``x`` (n, m): the same steps and numbers (odd
    extension, forward pass from ``zi·x₀``, backward pass from ``zi·y_end``, trim), computed on
    the transposed array so that ``scipy.signal.sosfilt`` runs along contiguous rows without
    copies, and returned column-major (what LAPACK wants of a block of regressor columns)."""
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    pad = min(int(np.ceil(PAD_PERIODS * rate / cutoff)), n - 1)
    if x.ndim != 2 or pad < 1:
        return np.asfortranarray(lowpass(x, cutoff, rate, order))
    if not 0 < cutoff < 0.5 * rate:
        raise OptionError(f"cutoff = {cutoff} Hz must lie in (0, {0.5 * rate:g}) Hz, below the "
                          f"Nyquist frequency of {rate:g} Hz sampling")
    sos, zi = _butterworth(order, float(cutoff), float(rate))
    xt = x.T
    ext = np.empty((x.shape[1], n + 2 * pad))
    ext[:, pad:pad + n] = xt
    ext[:, :pad] = 2 * xt[:, :1] - xt[:, pad:0:-1]
    ext[:, pad + n:] = 2 * xt[:, -1:] - xt[:, -2:-(pad + 2):-1]
    sos = sos.copy()                                        # scipy wants it writable
    y, _ = scipy.signal.sosfilt(sos, ext, axis=-1, zi=zi[:, None, :] * ext[None, :, :1])
    y = np.ascontiguousarray(y[:, ::-1])
    y, _ = scipy.signal.sosfilt(sos, y, axis=-1, zi=zi[:, None, :] * y[None, :, :1])
    return np.asfortranarray(y[:, ::-1][:, pad:pad + n].T)


def lowpass_power(freqs: np.ndarray, cutoff: float, rate: float, order: int = 4) -> np.ndarray:
    """The power response ``|H(f)|⁴`` of :func:`lowpass` (the Butterworth filter run forward and
    backward: its magnitude squared, then squared again for power) at ``freqs`` (Hz): the digital
    filter's own response (``scipy.signal.sosfreqz`` of the same sections), not the analogue
    ``(1 + (f/f_c)^{2n})^{-2}``, which it departs from near the Nyquist frequency."""
    sos, _ = _butterworth(int(order), float(cutoff), float(rate))
    _, h = scipy.signal.sosfreqz(sos, worN=np.asarray(freqs, dtype=float), fs=float(rate))
    return np.abs(h) ** 4


@functools.lru_cache(maxsize=64)
def impulse_response(cutoff: float, rate: float, order: int = 4) -> np.ndarray:
    """The zero-phase low-pass's impulse response (:func:`lowpass` of a unit sample), ``n``
    samples centred on sample ``n // 2`` (``n ≈ 40 rate / cutoff``, odd: its tails have died
    out). Shared, read-only."""
    n = int(np.ceil(40 * rate / cutoff)) | 1
    impulse = np.zeros(n)
    impulse[n // 2] = 1.0
    h = lowpass(impulse, cutoff, rate, order)
    h.flags.writeable = False
    return h


@functools.lru_cache(maxsize=64)
def settling_time(cutoff: float, rate: float, order: int = 4, energy: float = 0.99) -> float:
    """Half-width (s) of the zero-phase low-pass's impulse response (:func:`lowpass`) that holds
    ``energy`` of its energy: within that time of a recording's ends the filtered signal depends
    on samples before or after the recording, which its odd-reflection padding only guesses."""
    power = impulse_response(cutoff, rate, order) ** 2
    # symmetric about the centre: grow the window until it holds the fraction asked for
    centre = power.size // 2
    cumulative = power[centre] + 2 * np.cumsum(power[centre + 1:])
    k = int(np.searchsorted(cumulative, energy * power.sum()))
    return (k + 1) / rate


def central_difference(x: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives of uniformly sampled ``x`` by central differences.

    Interior: ``(x_{k+1} − x_{k−1})/2h`` and ``(x_{k+1} − 2x_k + x_{k−1})/h²`` (errors
    ``h² x'''/6`` and ``h² x''''/12``); second-order one-sided formulas at the two ends.
    """
    x = np.asarray(x, dtype=float)
    if x.shape[0] < 4:
        raise DatasetError(f"central differences need at least 4 samples, got {x.shape[0]}")
    h = 1.0 / rate
    dx = np.gradient(x, h, axis=0, edge_order=2)
    ddx = np.empty_like(x)
    ddx[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / h ** 2
    ddx[0] = (2 * x[0] - 5 * x[1] + 4 * x[2] - x[3]) / h ** 2
    ddx[-1] = (2 * x[-1] - 5 * x[-2] + 4 * x[-3] - x[-4]) / h ** 2
    return dx, ddx


def savgol_cutoff(window: int, rate: float, polyorder: int = 3) -> float:
    """The −3 dB frequency (Hz) of the Savitzky–Golay smoother of ``window`` samples.

    Its weights are the centre value of the least-squares polynomial fit, ``e_0ᵀ V⁺`` with
    ``V`` the Vandermonde matrix of the window's sample offsets scaled to ``[−1, 1]`` (exact in
    floating point for any window length); the cut-off is the first frequency where the
    magnitude response falls to ``1/√2``, interpolated linearly on a grid of 2048 steps up to
    3 × Schafer's estimate, then up to Nyquist (Nyquist if it never falls that low).
    """
    x = np.linspace(-1.0, 1.0, window)
    weights = np.linalg.pinv(np.vander(x, polyorder + 1, increasing=True))[0]
    estimate = (polyorder + 1) * rate / max(3.2 * window - 4.6, 1e-9)
    for top in (min(3.0 * estimate, 0.5 * rate), 0.5 * rate):
        f = np.linspace(0.0, top, 2049)
        mag = np.abs(scipy.signal.freqz(weights, worN=f, fs=rate)[1])
        below = np.flatnonzero(mag < 1.0 / np.sqrt(2.0))
        if below.size:
            i = below[0]
            return float(f[i - 1] + (mag[i - 1] - 1.0 / np.sqrt(2.0)) / (mag[i - 1] - mag[i])
                         * (f[i] - f[i - 1]))
    return 0.5 * rate


def savgol_window(cutoff: float, rate: float, polyorder: int = 3) -> int:
    """The odd window length whose Savitzky–Golay smoother has its −3 dB point
    (:func:`savgol_cutoff`) closest to ``cutoff``.

    Schafer's rule ``w = ((p + 1) f_s / f_c + 4.6) / 3.2`` (Schafer 2011) alone puts the −3 dB
    point at 0.8–0.9 × ``cutoff`` (0.6–0.8 × below 25 samples); the window is rescaled by that
    ratio (the cut-off is nearly ∝ 1/w) and then moved by 2 while that brings it closer.
    """
    if not 0 < cutoff < 0.5 * rate:
        raise OptionError(f"cutoff = {cutoff} Hz must lie in (0, {0.5 * rate:g}) Hz")
    smallest = polyorder + 2 if polyorder % 2 else polyorder + 1      # odd, > polyorder

    def odd(n: float) -> int:
        k = max(int(round(n)), smallest)
        return k + 1 if k % 2 == 0 else k

    w = odd(((polyorder + 1) * rate / cutoff + 4.6) / 3.2)
    w = odd(w * savgol_cutoff(w, rate, polyorder) / cutoff)
    error = {}

    def miss(n: int) -> float:
        if n not in error:
            error[n] = abs(savgol_cutoff(n, rate, polyorder) - cutoff)
        return error[n]

    for step in (2, -2):
        while w + step >= smallest and miss(w + step) < miss(w):
            w += step
    return w


def savgol_derivatives(x: np.ndarray, rate: float, window: int, polyorder: int = 3
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed value, first and second derivative by Savitzky–Golay fits along axis 0."""
    x = np.asarray(x, dtype=float)
    if window > x.shape[0]:
        raise DatasetError(f"Savitzky–Golay window {window} is longer than the {x.shape[0]} "
                           "samples")
    total = scipy.signal.savgol_coeffs(window, polyorder).sum()
    if not abs(total - 1.0) < 1e-6:        # scipy's weights break for long windows, high orders
        raise OptionError(f"scipy's Savitzky–Golay weights for {window} samples at order "
                          f"{polyorder} are numerically broken (they sum to {total:.3g}, not 1; "
                          "order 5 breaks beyond ~700 samples): use a lower polyorder, a higher "
                          "cut-off, or derivative='central'")
    kw = dict(window_length=window, polyorder=polyorder, axis=0, mode="interp")
    return (scipy.signal.savgol_filter(x, **kw),
            scipy.signal.savgol_filter(x, deriv=1, delta=1.0 / rate, **kw),
            scipy.signal.savgol_filter(x, deriv=2, delta=1.0 / rate, **kw))


def samples_per_period(period: float, rate: float) -> int:
    """``period × rate`` as an integer; raises :class:`DatasetError` unless it is one."""
    p = period * rate
    if abs(p - round(p)) > 1e-6 * max(p, 1.0) or round(p) < 4:
        raise DatasetError(f"period × rate = {period} s × {rate} Hz = {p:.9g} samples: "
                           "frequency-domain processing needs a whole number (≥ 4) of samples "
                           "per period")
    return int(round(p))


def period_average(x: np.ndarray, period: float, rate: float) -> tuple[np.ndarray, int]:
    """The mean over the whole periods of ``x`` (from its first sample), ``(P, ...)``, and the
    number of periods averaged. Trailing samples of an incomplete period are left out."""
    p = samples_per_period(period, rate)
    n = x.shape[0] // p
    if n < 1:
        raise DatasetError(f"the log has {x.shape[0]} samples, less than one period ({p})")
    return x[:n * p].reshape(n, p, *x.shape[1:]).mean(axis=0), n


def fourier_derivatives(x: np.ndarray, rate: float, period: float, harmonics: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Band-limited value, first and second derivative of one period of a periodic signal.

    ``x`` is one period (e.g. from :func:`period_average`), ``P`` samples. With its DFT
    ``X_k``, harmonics ``k > harmonics`` are zeroed and

    .. math:: \dot x = \mathcal F^{-1}[(i k \omega_f) X_k], \quad
              \ddot x = \mathcal F^{-1}[-(k \omega_f)^2 X_k], \quad \omega_f = 2\pi/T

    (the Nyquist bin, if kept, is dropped from the derivatives: its sign is ambiguous).
    """
    x = np.asarray(x, dtype=float)
    p = x.shape[0]
    if harmonics < 1:
        raise OptionError(f"harmonics = {harmonics}; keep at least the fundamental")
    spec = np.fft.rfft(x, axis=0)
    k = np.arange(spec.shape[0])
    keep = k <= harmonics
    shape = (-1,) + (1,) * (x.ndim - 1)
    spec = spec * keep.reshape(shape)
    iw = (1j * 2 * np.pi / period * k).reshape(shape)
    if p % 2 == 0 and keep[-1]:
        dspec = spec.copy()
        dspec[-1] = 0
    else:
        dspec = spec
    return (np.fft.irfft(spec, n=p, axis=0), np.fft.irfft(iw * dspec, n=p, axis=0),
            np.fft.irfft(iw ** 2 * dspec, n=p, axis=0))


def hampel(x: np.ndarray, window: int = 11, n_sigma: float = 6.0,
           t: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    r"""Replace outliers by the running median; returns ``(cleaned, outlier mask)``.

    Sample ``k`` of a channel is an outlier when ``|x_k − m_k| > n_σ · s_k`` (Hampel 1974), with
    ``m_k`` the median of the ``window`` samples centred on ``k`` less their trend (the median
    of their successive slopes over the stamps ``t``, default the sample index, which neither a
    spike nor a step moves: a torque that changes by several noise σ per sample hides no spike
    in its slope), *and* ``x_k`` lies outside
    ``[min(l_k, r_k) − n_σ s_k, max(l_k, r_k) + n_σ s_k]``, ``l_k`` and ``r_k`` the medians of
    the half windows before and after it: a sample between the levels on its two sides is a
    step (a Coulomb torque reversing with the velocity, a payload set down), physics rather
    than a glitch, which departs from both. The scale ``s_k`` is the largest of

    * the local MAD ``1.4826 · median_j |x_j − m_k|`` over the window;
    * the third quartile of ``|x_j − m_j|`` over the block of :data:`HAMPEL_SCALE_WINDOWS`
      windows that holds ``k``, over its value for Gaussian noise (1.1503 σ): eleven samples
      of noise that is not Gaussian (a controller chattering between two levels, a current's
      ripple) often have a MAD of nearly nothing, and their quartile sees it; it breaks down
      only when a quarter of the block is glitches;
    * the smallest non-zero step between consecutive samples of the channel, so that on a flat
      stretch of an encoder signal one count is not an outlier, and at least the float32
      rounding step of its largest value (:data:`FLOAT32_EPS`): a noise-free signal (a
      simulation) has no other scale, and loggers often store float32.

    A smooth signal is never flagged (at an extremum the ratio is about 1).
    """
    x = as_2d("x", x)
    if window < 3 or window % 2 == 0:
        raise OptionError(f"hampel window = {window}; it must be odd and ≥ 3")
    if x.shape[0] < window:
        raise DatasetError(f"hampel needs at least window = {window} samples, got {x.shape[0]}")
    half = window // 2
    padded = np.pad(x, ((half, half), (0, 0)), mode="reflect")
    win = np.lib.stride_tricks.sliding_window_view(padded, window, axis=0)  # (N, nv, window)
    # each window less its robust trend, the median of its successive slopes
    k = np.arange(x.shape[0], dtype=float) if t is None else np.asarray(t, dtype=float)
    tw = np.lib.stride_tricks.sliding_window_view(
        np.pad(k, half, mode="reflect", reflect_type="odd"), window)[:, None, :]   # (N, 1, w)
    slope = np.median(np.diff(win, axis=2) / np.diff(tw, axis=2), axis=2)
    win = win - slope[:, :, None] * (tw - tw[:, :, half:half + 1])
    med = np.median(win, axis=2)
    scale = 1.4826 * np.median(np.abs(win - med[:, :, None]), axis=2)
    level = _block_quartile(np.abs(x - med), HAMPEL_SCALE_WINDOWS * window) / GAUSS_Q75
    steps = np.abs(np.diff(x, axis=0))
    floor = np.array([np.min(s[s > 0]) if np.any(s > 0) else 0.0 for s in steps.T])
    floor = np.maximum(floor, FLOAT32_EPS * np.max(np.abs(x), axis=0))
    thr = n_sigma * np.maximum(np.maximum(scale, level), floor)
    left = np.median(win[:, :, :half], axis=2)
    right = np.median(win[:, :, half + 1:], axis=2)
    outside = (x < np.minimum(left, right) - thr) | (x > np.maximum(left, right) + thr)
    mask = (np.abs(x - med) > thr) & outside
    return np.where(mask, med, x), mask


def _block_quartile(r: np.ndarray, block: int) -> np.ndarray:
    """Per sample, the third quartile of the columns of ``r`` (N, nv) over the consecutive block
    of ``block`` samples that holds it (the last block takes the remainder too)."""
    n = r.shape[0]
    count = max(n // block, 1)
    edges = np.linspace(0, n, count + 1).astype(int)
    out = np.empty_like(r)
    for a, b in zip(edges[:-1], edges[1:]):
        out[a:b] = np.percentile(r[a:b], 75, axis=0)
    return out


def stuck_samples(tau: np.ndarray, q: np.ndarray, run: int = 3, max_repeats: float = 0.01
                  ) -> np.ndarray:
    """``True`` for the torque samples (N, nv) that repeat the value before them in a run of at
    least ``run`` equal samples while the same joint's position changed over the run, on
    channels where consecutive equal samples are otherwise rare (at most ``max_repeats`` of the
    steps): a logger that re-sent the last value of a channel that never holds still while the
    joint moved on. The first sample of each run is genuine and not marked. A joint at rest
    (its position constant over the run: a simulated torque without noise holds still too) and
    channels that repeat often (a quantised current) are left alone."""
    tau, q = as_2d("tau", tau), as_2d("q", q)
    mask = np.zeros(tau.shape, dtype=bool)
    if tau.shape[0] < 2:
        return mask
    same = np.diff(tau, axis=0) == 0                     # (N−1, nv): x[k+1] == x[k]
    for j in np.flatnonzero(same.mean(axis=0) <= max_repeats):
        padded = np.concatenate([[False], same[:, j], [False]])
        edges = np.flatnonzero(np.diff(padded.astype(int)))
        for a, b in zip(edges[::2], edges[1::2]):        # same[a:b] all True: x[a..b] equal
            if b - a + 1 >= run and q[b, j] != q[a, j]:
                mask[a + 1:b + 1, j] = True
    return mask


def bridge(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``x`` with the samples ``mask`` marks replaced by linear interpolation (in sample index)
    between the unmarked samples around them, per channel (held at the ends)."""
    x = as_2d("x", x).copy()
    k = np.arange(x.shape[0])
    for j in np.flatnonzero(mask.any(axis=0) & ~mask.all(axis=0)):
        bad = mask[:, j]
        x[bad, j] = np.interp(k[bad], k[~bad], x[~bad, j])
    return x


def low_speed_mask(dq: np.ndarray, threshold: float | Sequence[float]) -> np.ndarray:
    """``True`` for the samples to keep: every joint's ``|q̇|`` at least ``threshold`` (rad/s,
    scalar or per joint)."""
    dq = as_2d("dq", dq)
    thr = np.broadcast_to(np.asarray(threshold, dtype=float), (dq.shape[1],))
    return np.all(np.abs(dq) >= thr, axis=1)


def held_still(q: np.ndarray) -> np.ndarray:
    """``True`` for each joint whose positions trace no motion the sampling resolves: constant,
    or consecutive samples as far apart as any two of the log — the mean square successive
    difference at least the variance, ``mean(Δq²) ≥ var(q)`` (von Neumann's ratio
    ``δ²/s² = 2(1 − ρ₁)`` at least 1, lag-1 correlation ``ρ₁ ≤ ½``; von Neumann 1941,
    doi:10.1214/aoms/1177731677). Samples drawn independently (a joint held by its brake whose
    encoder flickers between counts, however seldom; independent states rather than a
    trajectory, as :mod:`consistid.data.recordings` tells them) have ``δ²/s² ≈ 2``; a motion
    sampled ``k`` times per period ``2(1 − cos(2π/k))``, below 1 from ``k = 7`` on."""
    q = as_2d("q", q)
    if q.shape[0] < 2:
        return np.ones(q.shape[1], dtype=bool)
    successive = np.mean(np.diff(q, axis=0) ** 2, axis=0)
    return (np.ptp(q, axis=0) == 0) | (successive >= np.var(q, axis=0))


def estimate_bandwidth(q: np.ndarray, rate: float, fraction: float = 0.9999) -> float:
    """The excitation bandwidth (Hz): the frequency below which ``fraction`` of the motion's
    power lies in every moving joint's detrended, Hann-windowed position (the largest over
    joints).

    Where the raw spectrum's ``fraction`` falls on noise (its bin, averaged with the two on
    each side, within :data:`NOISE_MARGIN` of the noise's level, or at more than twice the
    frequency the excess below gives), the motion's power is what
    the periodogram holds above its noise: per bin, the power in excess of
    :data:`NOISE_MARGIN` × the running median over :data:`NOISE_WINDOW` of the bins at and
    above it (the noise's local level, white or
    coloured, which the few lines of an excitation band do not move). Noise whose power is a
    fraction ``ε`` of the motion's would otherwise set the bandwidth wherever the fraction
    ``1 − ε`` lies: on a jittered log whose stamps are off by ``δ``, the error ``q̇ δ`` is ~1 %
    of a slow motion, and set it at 100–600 Hz. Elsewhere (a clean log) the raw spectrum's.

    Positions are used, not velocities: their noise is tiny compared with the motion. Joints
    :func:`held_still` are left out: their spectrum is rounding or encoder noise, flat up to the
    Nyquist frequency, and would set every joint's cut-off there (when no joint moves by that
    rule — independent states, not a trajectory — every joint that varies counts, and then
    without the noise's subtraction, which would leave nothing).
    """
    q = as_2d("q", q)
    if q.shape[0] < 16:
        raise DatasetError(f"{q.shape[0]} samples are too few to estimate a bandwidth")
    x = scipy.signal.detrend(q, axis=0) * np.hanning(q.shape[0])[:, None]
    power = np.abs(np.fft.rfft(x, axis=0)) ** 2
    freqs = np.fft.rfftfreq(q.shape[0], 1.0 / rate)
    moving = power.sum(axis=0) > 0
    resolved = moving & ~held_still(q)
    if not moving.any():
        raise DatasetError("the positions do not move: no excitation bandwidth")
    if resolved.any():
        moving = resolved
        level = NOISE_MARGIN * _noise_level(power)
        raw = _fraction_bin(power, fraction)
        # where the raw spectrum's bin is noise (no more than the margin over its level), the
        # noise set it: the motion's power is the excess over the noise
        smooth = scipy.ndimage.uniform_filter1d(power, 5, axis=0, mode="reflect")
        cols = np.arange(power.shape[1])
        excess = np.maximum(power - level, 0.0)
        # or where the excess puts it at less than half: the raw point is then set by power
        # that is not the motion's (leakage moves it by a few bins only)
        noisy = (smooth[raw, cols] <= level[raw, cols]) | (
            2 * _fraction_bin(excess, fraction) < raw)
        use = noisy & (excess.sum(axis=0) > 0)           # else no line stands out: the raw
        power = np.where(use, excess, power)
    power = power[:, moving]
    idx = _fraction_bin(power, fraction)
    return float(max(freqs[idx].max(), freqs[1]))


def _fraction_bin(power: np.ndarray, fraction: float) -> np.ndarray:
    """Per column of a periodogram, the first bin below which ``fraction`` of its power lies
    (0 for a column without power)."""
    total = power.sum(axis=0)
    cum = np.cumsum(power, axis=0) / np.where(total > 0, total, 1.0)
    return np.argmax(cum >= fraction, axis=0)


def _noise_level(power: np.ndarray) -> np.ndarray:
    """The running median of each column of a periodogram over the :data:`NOISE_WINDOW` of its
    bins at and above each (at least 15; the top end reflected): looking up, a window at the
    band's top harmonic holds the noise beyond it, not the lines below it, however few bins a
    short log gives the band. Raised towards the median over the window centred on the bin,
    by at most :data:`CENTRED_GAIN`: where coloured noise falls with frequency (AR(1) position
    noise beyond its corner, ``∝ 1/f²``) the bins above read a fraction of its level a window
    up, and one noise bin in ~30 rather than ~1000 would pass :data:`NOISE_MARGIN` (on a slow
    joint's 5 mrad motion under AR(1) noise, φ = 0.95, that read 3.3–9.8 × the band). Uncapped,
    the centred window at the top harmonic of a short log holds the band's own lines and reads
    the whole band as noise (321 Hz for a 2.5 Hz band on a 2 s log)."""
    width = max(int(NOISE_WINDOW * power.shape[0]) | 1, 15)
    above = scipy.ndimage.median_filter(power, size=(width, 1), mode="reflect",
                                        origin=(-(width // 2), 0))
    centred = scipy.ndimage.median_filter(power, size=(width, 1), mode="reflect")
    return np.maximum(above, np.minimum(centred, CENTRED_GAIN * above))


def default_cutoff(bandwidth: float, rate: float) -> float:
    """``min(10 × bandwidth, 0.4 × rate)`` (Hz) (:data:`CUTOFF_FACTOR`)."""
    if not bandwidth > 0:
        raise OptionError(f"bandwidth = {bandwidth} Hz must be positive")
    return float(min(CUTOFF_FACTOR * bandwidth, MAX_CUTOFF_FRACTION * rate))
