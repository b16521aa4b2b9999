"""The dataset's runs, checked and prepared for the diagnosis.

A :class:`GapRun` is one closed-loop run on the controller's sample grid: command
``r_k`` [in] and reading ``y_k`` [in] at the instants ``t_k = t_0 + k·T``; ``scale``
[in] is the NRMSE denominator ‖y − mean(y)‖/√n. ``noise`` [in] estimates the reading
noise the rig's controller saw: the reading minus its local quintic smoothing
(Savitzky–Golay, :data:`NOISE_WINDOW` samples, which passes a 25 Hz oscillation to within
0.01 mil, so a ringing step injects no signal, and still catches 72 % of white noise's variance). Models are simulated with their
controller reading it too, so that effects the noise dithers (backlash, deadband,
stiction) act as they did on the rig. It is zero for the instability run, whose
large oscillation no smoother separates from the noise to the needed precision. The runs are put on the sample grid
(time stamps rounded for printing are read back onto it: :func:`~grader.datasets.sampling.sample_times`, whose
check that each row is one controller sample the dataset's load has made). Checks raise :class:`DiagnosisError`
naming the run: fewer than two runs to compare, and a manifest gain the recorded controller output ``u``
contradicts. A run too short, or whose position never changes, is set aside with a note; a reading
that jumps out and back within one sample is mended with one (:mod:`grader.gap.glitches`). A run is
compared over at most :data:`MAX_COMPARED` seconds after its command.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import convolve1d
from scipy.optimize import least_squares
from scipy.signal import savgol_coeffs

from grader.datasets import Dataset, Run
from grader.datasets.sampling import printed_resolution, sample_times
from grader.errors import DiagnosisError
from grader.gap import glitches
from grader.model.params import Controller
from grader.model.rig_setup import DAC_LIMIT

Array = NDArray[np.float64]
#: Least recorded time after the command starts [s].
MIN_DURATION = 0.2
#: [s] after its command, the most of a run compared: every model evaluation simulates every sample (a 700 s record
#: took a minute), while a lab run settles, tracks or oscillates for a few seconds.
MAX_COMPARED = 30.0
#: Fewest runs: the held-out gap of a run needs a model fitted to another.
MIN_RUNS = 2
#: Relative disagreement between the manifest gain and the gain ``u`` implies that is an error.
GAIN_TOLERANCE = 0.1
#: Quantile of the control law's |b| at which a row's weight in the implied gain is capped.
GAIN_WEIGHT_CAP = 0.99
NOISE_WINDOW, NOISE_ORDER = 13, 5
#: Every weight of the quintic fit over 13 points, evaluated at any of them, is a multiple of 1/9724
#: (11·13·17·4). Rounded to that grid, the weights are exact: the same bytes on any CPU, where
#: :func:`scipy.signal.savgol_coeffs`' least squares differs between BLAS kernels in the 14th digit.
_DENOMINATOR = 9724.0
#: Row k: the weights of the quintic fitted to a window, evaluated at its k-th point.
_FIT = np.array([np.round(savgol_coeffs(NOISE_WINDOW, NOISE_ORDER, pos=k, use="dot") * _DENOMINATOR)
                 for k in range(NOISE_WINDOW)]) / _DENOMINATOR
#: The quintic smoothing's weights (the centre row), computed once: :func:`scipy.signal.savgol_filter`
#: recomputes them at every call, which costs four times the filtering in a fit's thousands of calls.
SMOOTH = _FIT[NOISE_WINDOW // 2].copy()


def quintic_smooth(y: Array) -> Array:
    """The quintic Savitzky–Golay smoothing of ``y`` (at least :data:`NOISE_WINDOW` samples), as
    :func:`scipy.signal.savgol_filter` (mode ``interp``: the first and last half-windows from the quintic fitted
    to the first and last window) computes it, with the exact weights above and sums in a fixed order."""
    if y.size < NOISE_WINDOW:
        raise ValueError(f"quintic smoothing needs at least {NOISE_WINDOW} samples, got {y.size}")
    h = NOISE_WINDOW // 2
    out = convolve1d(y, SMOOTH, mode="nearest")
    out[:h] = np.sum(_FIT[:h] * y[:NOISE_WINDOW], axis=1)
    out[-h:] = np.sum(_FIT[-h:] * y[-NOISE_WINDOW:], axis=1)
    return out


@dataclass(frozen=True)
class GapRun:
    """One run on the sample grid (see module docstring)."""

    name: str
    kind: str
    controller: Controller
    t: Array
    r: Array
    y: Array
    u: Array | None
    start: float
    scale: float
    noise: Array
    #: the valve's null current as a shift of the controller output [V], and that shift through the feedback gain,
    #: null_u/k_fb [in] (:mod:`grader.gap.null`): the model's inputs, not the rig's
    null_u: float = 0.0
    null_offset: float = 0.0

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def command_shift(self) -> float:
        """The command shift [in] that holds the valve's null in this run (:func:`null_shift`)."""
        return null_shift(self.controller, self.null_offset)


def null_shift(c: Controller, offset: float) -> float:
    """The command shift [in] that holds a valve null of ``offset`` [in] (the controller output's shift through the
    feedback gain, null_u/k_fb) in a P or PD loop at its gain; a PI loop's integrator holds it: 0."""
    return offset / c.Kp if c.Ki == 0.0 and c.Kp != 0.0 else 0.0


def command_start(t: Array, r: Array) -> float:
    """Time [s] at which the command first changes."""
    moved = np.flatnonzero(np.abs(r - r[0]) > 1e-12)
    return float(t[moved[0]]) if moved.size else float(t[0])


def _on_grid(raw: Run, T: float) -> tuple[Run, GapRun, list[str]]:
    """The run's rows as controller samples (one row per sample, evenly spaced: :func:`sample_times`), over at most
    :data:`MAX_COMPARED` s after the command, its glitches mended (:mod:`grader.gap.glitches`): the recorded run
    with those mended, the run on the grid and the notes on the glitches."""
    t = sample_times(raw, T)
    run = replace(raw, t=t) if t is not raw.t else raw
    start = command_start(run.t, run.r)
    n = int(np.searchsorted(run.t, start + MAX_COMPARED, side="right"))
    if n < run.t.size:  # a long record: its first MAX_COMPARED seconds after the command (a note says so)
        run = replace(run, t=run.t[:n], r=run.r[:n], y=run.y[:n], u=None if run.u is None else run.u[:n])
    where = f"run {run.name} ({run.spec.file})"
    if run.t[-1] - start < MIN_DURATION or run.t.size < 50:
        raise _Unusable(f"{where}: only {max(run.t[-1] - start, 0) * 1e3:.0f} ms recorded after the command starts "
                        f"({run.t.size} rows in all); the diagnosis needs at least {MIN_DURATION * 1e3:.0f} ms after "
                        "it and 50 rows")
    mended = glitches.mend(run.y, run.t, where, line=run.line)
    if mended.flat:
        many = "s" if len(mended.rows) > 1 else ""
        but = f" apart from the reading{many} at row{many} {', '.join(map(str, mended.rows))}" if mended.rows else ""
        raise _Unusable(f"{where}: the position never changes{but}; nothing to compare")
    y, notes = mended.y, mended.notes
    if y is not run.y:
        run, raw = replace(run, y=y), replace(raw, y=np.concatenate([y, raw.y[y.size:]]))
    noise = np.zeros(run.t.size) if run.spec.kind == "instability" else run.y - quintic_smooth(run.y)
    gap_run = GapRun(run.name, run.spec.kind, run.controller, run.t, run.r, run.y, run.u, start, float(np.std(run.y)),
                     noise)
    return raw, gap_run, notes


#: A run whose first readings lie further from its first command than this many times the noise floor and this
#: share of the command's range does not start at rest at its command, as the model's simulation of it does.
START_NOISE, START_SHARE = 10.0, 0.05
START_ROWS = 5  # first readings averaged: one reading's noise would need a larger bar


def start_offset_note(run: GapRun, floor: float) -> str | None:
    """A note where ``run`` does not start at rest at its command (the mean of its first readings off the first
    command by more than :data:`START_NOISE` × the noise ``floor`` [in] and :data:`START_SHARE` of the command's
    range), else None: the logger started late, or the rig was still moving or held off by friction."""
    off = float(np.mean(run.y[:START_ROWS]) - run.r[0] - run.command_shift)
    if abs(off) <= max(START_NOISE * floor, START_SHARE * float(np.ptp(run.r))):
        return None
    return (f"run {run.name} starts {off:+.3g} in from its command, where the model starts it at rest: the logger "
            "started late, or the rig was still moving or held off by friction; its first part is not comparable")


def cut_note(run: GapRun, recorded: Run) -> str | None:
    """A note where ``run`` keeps only the first :data:`MAX_COMPARED` seconds after its command of ``recorded``."""
    if run.n == recorded.t.size:
        return None
    return (f"run {run.name}: its first {MAX_COMPARED:g} s after the command are compared (the record has "
            f"{recorded.t[-1] - recorded.t[0]:.4g} s)")


def control_law(c: Controller, e: Array, T: float) -> Array:
    """u_k [V] of the digital controller for the error sequence ``e`` (already times k_fb)."""
    d = np.diff(e, prepend=0.0)
    return c.Kp * e + c.Ki * T * np.cumsum(e) + c.Kd * d / T


def controller_output(run: GapRun, k_fb: float, T: float) -> Array:
    """u_k [V]: the recorded controller output, else the control law on the readings (within the DAC's range)."""
    if run.u is not None:
        return run.u
    return np.clip(control_law(run.controller, k_fb * (run.r - run.y), T), -DAC_LIMIT, DAC_LIMIT)


def current_demand(runs: list[GapRun], k_fb: float, T: float, Kamp: float) -> float:
    """The largest valve current [mA] the runs' controller asks for (Kamp·|u|)."""
    return max(float(np.max(np.abs(controller_output(r, k_fb, T)))) for r in runs) * Kamp


def implied_feedback_gain(run: GapRun, T: float) -> float | None:
    """The k_fb [V/in or 1] that makes the manifest's gains reproduce the recorded u from the run's reading, or None
    without u."""
    fit = _gain_fit(run, T, run.y)
    return None if fit is None else fit[0]


def _gain_fit(run: GapRun, T: float, y: Array) -> tuple[float, float] | None:
    """(the k_fb the recorded u implies from reading ``y``, the mean |u − k_fb·law| [V] it leaves on the rows used),
    or None without u or without 20 rows that move it."""
    if run.u is None:
        return None
    basis = control_law(run.controller, run.r - y, T)
    use = (np.abs(run.u) < 0.95 * DAC_LIMIT) & (np.abs(basis) > 1e-12)
    if use.sum() < 20 or not np.any(np.abs(run.u[use]) > 1e-6):
        return None
    b, u = basis[use], run.u[use]
    # the least-absolute-deviation slope through 0, the |b|-weighted median of u/b: rows where a coarsely printed u
    # reads 0 do not set it; each weight is capped at the 99th percentile of |b|, so that a few rows whose recorded
    # y the controller never saw (a logger's spike, which makes |b| huge there) do not set it either
    w = np.minimum(np.abs(b), np.quantile(np.abs(b), GAIN_WEIGHT_CAP))
    k = float(np.quantile(u / b, 0.5, weights=w, method="inverted_cdf"))
    return k, float(np.mean(np.abs(u - k * b)))


def _seen(run: GapRun, T: float) -> tuple[Array, float] | None:
    """The reading the controller saw and the k_fb the recorded u implies from it (:func:`_gain_fit`), or None
    without u. Where the reading as compared still holds glitches (too many to mend: compared as recorded), that is
    the reading as recorded or with them mended, whichever u follows more closely: a logger's glitch is a reading
    the controller never saw (a PI's integral of four 5 in spikes took the gains to 1.43 times the manifest's), a
    sensor's fault one it saw."""
    found = glitches.search(run.y)
    fits = [(y, f) for y in ([run.y, found.mended] if found.found else [run.y]) if (f := _gain_fit(run, T, y))]
    if not fits:
        return None
    y, (k, _) = min(fits, key=lambda yf: yf[1][1])
    return y, k


def u_resolution(u: Array) -> float:
    """The resolution [V] the controller output ``u`` was printed with (0 for all zeros): rows at rest print 0 in
    any format, and would read as whole volts, so they are left out."""
    printed = u[u != 0]
    return printed_resolution(printed) if printed.size else 0.0


def seen_reading(run: GapRun, T: float) -> Array | None:
    """The reading the controller saw (:func:`_seen`), or None without u."""
    seen = _seen(run, T)
    return None if seen is None else seen[0]


def controller_gain(run: GapRun, T: float) -> float | None:
    """The k_fb the recorded u implies (:func:`implied_feedback_gain`) from the reading the controller saw
    (:func:`_seen`)."""
    seen = _seen(run, T)
    return None if seen is None else seen[1]


#: The controller's terms, in the order of :func:`control_law`'s.
TERMS = ("Kp", "Ki", "Kd")
#: A term whose gain u implies differs from the manifest's by more than GAIN_TOLERANCE (or is not in the manifest)
#: is noted where the difference moves u by more than TERM_SHARE of u's RMS and by at least the resolution u was
#: printed with (a u printed to 0.1 V lets a derivative's gain wander by up to half a step's RMS: rounding, not a
#: wrong gain).
TERM_SHARE = 0.05


@dataclass(frozen=True)
class TermFit:
    """The gains Kp, Ki, Kd the recorded u implies (:func:`term_gains`) beside the manifest's (``given``); for each,
    the RMS by which its difference from the manifest's moves u, as a share of u's RMS (``moved``) and in steps of
    the resolution u was printed with (``steps``)."""

    given: dict[str, float]
    gains: dict[str, float]
    moved: dict[str, float]
    steps: dict[str, float]

    def visible(self, term: str) -> bool:
        """Whether the difference in ``term`` shows in u: more than TERM_SHARE of its RMS and a printed step."""
        return self.moved[term] > TERM_SHARE and self.steps[term] >= 1.0

    def off(self) -> list[str]:
        """The terms whose gain u implies is not the manifest's: visible, and more than GAIN_TOLERANCE away (or not
        in the manifest)."""
        return [t for t in TERMS if self.visible(t)
                and (self.given[t] == 0 or abs(self.gains[t] / self.given[t] - 1) > GAIN_TOLERANCE)]

    def shown(self) -> dict[str, float]:
        """The gains, with 0 for a term the manifest leaves 0 that does not show in u (a fitted Ki of 6e-07 is no
        integral gain)."""
        return {t: 0.0 if self.given[t] == 0 and not self.visible(t) else g for t, g in self.gains.items()}


def term_gains(run: GapRun, T: float, k_fb: float) -> TermFit | None:
    """The gains Kp, Ki, Kd that reproduce the recorded u from the reading the controller saw with feedback gain
    ``k_fb``, or None without u or 20 rows within the DAC's range. A robust least-squares fit (soft-L1 loss: a few
    rows the controller never saw do not set it) started from the manifest's gains; a gain the manifest leaves 0 is
    fitted too."""
    seen = _seen(run, T)
    if seen is None or run.u is None:
        return None
    e = k_fb * (run.r - seen[0])
    cols = np.column_stack([e, T * np.cumsum(e), np.diff(e, prepend=0.0) / T])
    use = np.abs(run.u) < 0.95 * DAC_LIMIT
    if use.sum() < 20:
        return None
    a, u = cols[use], run.u[use]
    size = np.sqrt(np.mean(a**2, axis=0))
    size[size == 0] = 1.0
    rms = float(np.sqrt(np.mean(u**2))) or 1.0
    c = np.array([run.controller.Kp, run.controller.Ki, run.controller.Kd])
    scaled = a / size  # columns of unit RMS: the fit's steps are alike in every coordinate
    fit = least_squares(lambda x: scaled @ x - u, c * size, loss="soft_l1", f_scale=0.01 * rms)
    g = fit.x / size
    moved = np.sqrt(np.mean((a * (g - c)) ** 2, axis=0))
    steps = moved / max(u_resolution(u), 1e-12)
    as_terms = lambda x: dict(zip(TERMS, map(float, x)))  # noqa: E731
    return TermFit(as_terms(c), as_terms(g), as_terms(moved / rms), as_terms(steps))


def _implied_text(gains: dict[str, float]) -> str:
    return ", ".join(f"{t} ≈ {g:.3g}" for t, g in gains.items())


def gain_notes(runs: list[GapRun], k_fb: float | None, T: float) -> list[str]:
    """A note for each run whose recorded u implies a term's gain other than the manifest's (:meth:`TermFit.off`),
    where the gains as a whole passed :func:`check_gains` (a derivative gain wrong by a third, say, moves the
    median slope of u on the law little): the diagnosis simulates the manifest's gains."""
    out: list[str] = []
    for run in runs if k_fb is not None else []:
        terms = term_gains(run, T, k_fb)
        if terms is None or not (off := terms.off()):
            continue
        given = ", ".join(f"{t} = {terms.given[t]:g}" for t in off)
        out.append(f"run {run.name}: the manifest gives {given}, but the recorded controller output u implies "
                   f"{_implied_text({t: terms.gains[t] for t in off})}; the diagnosis simulates the manifest's gains, "
                   "so correct them if u is right (a filtered derivative, or an integrator that stops at the DAC's "
                   "limit, also shows here)")
    return out


def check_gains(runs: list[GapRun], k_fb: float | None, T: float, skip: frozenset[str] = frozenset()) -> float | None:
    """Raise if a run's recorded u contradicts its manifest gain (:func:`controller_gain`); returns the implied
    k_fb (median). Runs named in ``skip`` (a filtered derivative, :mod:`grader.gap.dfilter`) are not checked."""
    implied = {r.name: controller_gain(r, T) for r in runs if r.name not in skip}
    known = {n: v for n, v in implied.items() if v is not None}
    if not known:
        return None
    ref = k_fb if k_fb is not None else float(np.median(list(known.values())))
    for run in runs:
        v = known.get(run.name)
        if v is not None and (v <= 0 or abs(v / ref - 1) > GAIN_TOLERANCE):
            c = run.controller
            factor = v / ref
            terms = term_gains(run, T, ref)
            each = "" if terms is None else f"; term by term, {_implied_text(terms.shown())}"
            raise DiagnosisError(
                f"run {run.name}: the manifest gives Kp = {c.Kp:g} (Ki = {c.Ki:g}, Kd = {c.Kd:g}) but the recorded "
                f"controller output u implies gains {factor:.3g} times those (Kp ≈ {c.Kp * factor:.3g}){each}; "
                "correct the run's gains in the manifest"
            )
    return ref


class _Unusable(DiagnosisError):
    """A run with nothing to compare (too short, or a position that never changes): set aside with a note."""


def prepare_runs(dataset: Dataset, T: float) -> tuple[Dataset, list[GapRun], list[str]]:
    """The runs of ``dataset`` checked and on the sample grid: the dataset without the runs that hold nothing to
    compare, the runs kept, and a note naming each run set aside and why. Raises when fewer than
    :data:`MIN_RUNS` are left, or where a run's rows are not one per controller sample."""
    if len(dataset.runs) < MIN_RUNS:
        listed = "no runs" if not dataset.runs else f"one run ({dataset.runs[0].name})"
        raise DiagnosisError(f"{dataset.root.name}: the manifest lists {listed}; the diagnosis needs at least "
                             f"{MIN_RUNS} closed-loop runs (it predicts each run from the model fitted to the others)")
    kept: list[tuple[Run, GapRun]] = []
    reasons: list[str] = []
    mended: list[str] = []
    for raw in dataset.runs:
        try:
            run, gap_run, notes = _on_grid(raw, T)
        except _Unusable as exc:
            reasons.append(str(exc))
            continue
        kept.append((run, gap_run))
        mended += notes
    if len(kept) < MIN_RUNS:
        raise DiagnosisError(f"{dataset.root.name}: {len(kept)} of the manifest's {len(dataset.runs)} runs can be "
                             f"compared, and the diagnosis needs at least {MIN_RUNS}: {'; '.join(reasons)}")
    notes = [f"{reason}; the run is set aside" for reason in reasons] + mended
    return replace(dataset, runs=tuple(run for run, _ in kept)), [run for _, run in kept], notes


def truncated(run: GapRun, duration: float) -> GapRun:
    """The run's first ``duration`` seconds after the command starts (scale kept)."""
    n = int(np.searchsorted(run.t, run.start + duration, side="right"))
    if n >= run.n:
        return run
    u = None if run.u is None else run.u[:n]
    return replace(run, t=run.t[:n], r=run.r[:n], y=run.y[:n], u=u, noise=run.noise[:n])
