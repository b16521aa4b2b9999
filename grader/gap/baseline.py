"""The linear model the diagnosis starts from.

In order of preference:

1. ``key``: the model of an answer key (``--key``), at the manifest's sample time.
2. ``identified``: the students' full procedure (:func:`grader.identify.identify`) when
   the dataset has the calibration, flow-test and friction files and an instability run.
3. ``runs``: identified from the runs themselves. The closed loop depends only on
   products (g = 4β/Vt; a₂ = g·Kce, a₁ = g·A²/M, a₀/Kp = Kamp·k_fb·g·Kq·A/M), so
   β/Vt, Kce and the loop gain Kq·k_fb are fitted to the runs (the linear part of each
   run, before the amplifier or DAC limit) starting from the instability run's
   oscillation as the students read it. Kpot comes from the calibration file, else from
   the recorded controller output u, else (volts feedback) from the runs' loop gain over the
   flow test's Kq; Kq from the flow test, else it is fitted (nominal start: rated flow ÷
   rated current, the paper's 0.5 gpm at 50 mA).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from grader.datasets import Dataset
from grader.errors import DiagnosisError, GraderError, IdentificationError
from grader.gap.runs import GapRun, controller_output
from grader.identify import (
    FlowGainFit,
    OscillationFit,
    PotCalibration,
    coefficient_match,
    identify,
    match_sampled_poles,
    not_identifiable,
)
from grader.keys import read_key
from grader.model.effects import NO_EFFECTS
from grader.model.params import RigParams
from grader.model.rig import position_batch
from grader.model.rig_setup import DAC_LIMIT
from grader.precision import round_sig

Array = NDArray[np.float64]
RATED_FLOW = 0.5 * 231.0 / 60.0  # 0.5 gpm [in³/s]
TYPICAL = {"beta_over_Vt": 2.0e4, "Kce": 7.0e-4}
#: The loop fit moves ln β/Vt, ln Kce (and ln Kq) at most this far from its start (a factor of 55) ...
LOG_SPAN = 4.0
#: ... and ln β/Vt at most this far (a factor of 2.7) from the one the instability run's oscillation gives: its
#: frequency pins β/Vt (ω² ∝ β/Vt) even where the runs hold more than the linear loop can follow (a valve that
#: saturates at a third of the amplifier's current drove a free fit to the bound, 55 times the truth).
OSC_SPAN = 1.0
#: The baseline's values that come from identification (the rest is given).
_IDENTIFIED = ("Kq", "Kpot", "beta_over_Vt", "Kce", "B")


@dataclass(frozen=True)
class Baseline:
    """The linear model, where it came from, and notes for the report."""

    params: RigParams
    source: str
    method: str
    notes: tuple[str, ...] = ()
    #: Kpot is the runs' loop gain over the flow test's Kq (volts feedback, no calibration, no usable u): the
    #: flow test then cannot be held against the runs' loop gain (:func:`grader.gap.evidence.loop_gain`).
    kpot_from_flow_test: bool = False


def _given_params(ds: Dataset, Kq: float, Kpot: float, bv: float, kce: float) -> RigParams:
    g = ds.given
    return RigParams(A=g["A"], M=g["M"], Kamp=g["Kamp"], Kq=Kq, Kpot=Kpot, beta_over_Vt=bv, Kce=kce, B=0.0,
                     sample_time=g["sample_time"], feedback=ds.manifest.feedback,
                     supply_pressure=g["supply_pressure"], i_max=g["i_max"])


def from_key(path: str | Path, ds: Dataset) -> Baseline | str:
    """The key's model at the manifest's sample time and limits; or, when the key's data gave no
    model (β/Vt and Kce null), why not."""
    key = read_key(path)
    if key.feedback != ds.manifest.feedback:
        raise DiagnosisError(f"{Path(path).name}: the key uses '{key.feedback}' feedback but the dataset '{ds.manifest.feedback}'")
    if not key.identified:
        return f"the key {Path(path).name} has no model ({key.quantities['Kce'].reason})"
    g = ds.given
    p = key.params().with_(sample_time=g["sample_time"], i_max=g["i_max"], supply_pressure=g["supply_pressure"])
    return Baseline(p, "key", f"answer key {Path(path).name} (station {key.station})")


def _linear_part(run: GapRun, p: RigParams) -> int:
    """Samples before the controller output first nears the DAC or amplifier limit."""
    u = controller_output(run, p.k_fb, p.sample_time)
    limit = 0.9 * min(DAC_LIMIT, p.i_max / p.Kamp)
    over = np.flatnonzero(np.abs(u) >= limit)
    return int(over[0]) if over.size else run.n


def _oscillation(runs: Sequence[GapRun], p: RigParams) -> tuple[RigParams | None, str]:
    """``p`` with β/Vt and Kce from the instability run's oscillation, and where they come from; None (and why
    not) without a usable oscillation."""
    inst = [r for r in runs if r.kind == "instability"]
    if not inst:
        return None, "typical β/Vt and Kce (no instability run)"
    run = inst[0]
    try:
        osc = OscillationFit().fit(run.t, run.y, start=run.start)
        if not osc.usable_:
            return None, f"typical β/Vt and Kce ({osc.why_not_})"
        bv, kce = coefficient_match(omega=osc.omega_.value, kp_crit=run.controller.Kp, A=p.A, M=p.M, Kamp=p.Kamp,
                                    Kq=p.Kq, k_fb=p.k_fb)
        p = match_sampled_poles(p.with_(beta_over_Vt=bv, Kce=kce), kp=run.controller.Kp, sigma=osc.sigma_.value,
                                omega=osc.omega_.value)
    except (IdentificationError, GraderError):
        return None, "typical β/Vt and Kce (the instability run shows no clean oscillation)"
    return p, f"oscillation of run {run.name} at Kp = {run.controller.Kp:g}"


def fit_loop(runs: Sequence[GapRun], p0: RigParams, *, fit_kq: bool, bv_span: float = LOG_SPAN) -> RigParams:
    """Least squares of the linear loop (the compiled engine, no effect) on the runs' linear parts: ln β/Vt
    (within ``bv_span`` of p0's), ln Kce (and ln Kq), each within its span through x = span·sin(z).

    The same bytes under any BLAS kernel: the start is rounded to :data:`~grader.precision.SIGNIFICANT_DIGITS`
    (the oscillation's fit and the calibration differ in their last digits between kernels), the engine uses no
    BLAS, and MINPACK's Levenberg–Marquardt (``method="lm"``, its ``x_scale`` given: scipy 1.16 changed the
    default) neither. The valley is flat along Kce where a bound holds β/Vt: a BLAS-based solver's last-digit
    differences moved the optimum there by 1e-4."""
    p0 = _as_written(p0)
    used = [(run, n) for run in runs if (n := _linear_part(run, p0)) >= 20]
    if not used:
        return p0
    span = np.array([bv_span, LOG_SPAN, LOG_SPAN][:3 if fit_kq else 2])  # runs the linear model cannot follow

    def model(z: Array) -> RigParams:
        x = [s * math.sin(v) for s, v in zip(span, z)]
        kq = p0.Kq * math.exp(x[2]) if fit_kq else p0.Kq
        return p0.with_(beta_over_Vt=p0.beta_over_Vt * math.exp(x[0]), Kce=p0.Kce * math.exp(x[1]), Kq=kq)

    def resid(z: Array) -> Array:
        p = model(z)
        ys = position_batch([p] * len(used), [run.controller for run, _ in used], [NO_EFFECTS] * len(used),
                            [run.r[:n] + run.command_shift for run, n in used]).run()  # the valve's null held
        return np.concatenate([(y - run.y[:n]) / (run.scale * np.sqrt(n)) for y, (run, n) in zip(ys, used)])

    return model(least_squares(resid, np.zeros(span.size), method="lm", x_scale="jac").x)


def _calibrated_kpot(ds: Dataset, notes: list[str]) -> float | None:
    """Kpot [V/in] from the calibration file; with feedback in inches, which the loop does not need Kpot for, a
    calibration the identification cannot use (a flat one) is set aside with a note (None)."""
    assert ds.calibration is not None
    try:
        return PotCalibration().fit(ds.calibration["position"], ds.calibration["voltage"]).Kpot_.value
    except IdentificationError as exc:
        if ds.manifest.feedback == "volts":  # the loop gain carries Kpot
            raise
        reason = str(exc).removeprefix("calibration: ")
        notes.append(f"calibration {ds.manifest.calibration} not used ({reason}): the loop, fed back in inches, "
                     "does not need Kpot")
        return None


def _flow_kq(ds: Dataset, notes: list[str]) -> float | None:
    """Kq [in³/s/mA] from the flow test, or None (fitted to the runs instead, with a note): without one, or with
    one the identification cannot use (read on one side of the null only, flat, or saturating within one input step
    of the null)."""
    start = "Kq fitted to the runs (nominal start 0.5 gpm / rated current)"
    if ds.flow_test is None:
        notes.append(f"no flow test: {start}")
        return None
    try:
        kq = FlowGainFit(Kamp=ds.given["Kamp"]).fit(ds.flow_test["input"], ds.flow_test["flow"]).Kq_
    except IdentificationError as exc:
        kq = not_identifiable("in**3/s/mA", "flow test", str(exc).removeprefix("flow test: "))
    if kq.status == "ok":
        return kq.value
    notes.append(f"flow test {ds.manifest.flow_test} not used ({kq.reason}): {start}")
    return None


def _kpot_from_loop_gain(p: RigParams, kq: float) -> RigParams:
    """``p`` with Kq [in³/s/mA] set to ``kq`` and Kpot [V/in] moved so that the loop gain Kpot·Kq stays."""
    return p.with_(Kpot=p.Kpot * p.Kq / kq, Kq=kq)


def from_runs(ds: Dataset, runs: Sequence[GapRun], implied_kfb: float | None) -> Baseline:
    """The loop identified from the runs (see module docstring)."""
    notes: list[str] = []
    flow_notes: list[str] = []
    kq = _flow_kq(ds, flow_notes)
    volts = ds.manifest.feedback == "volts"
    kpot = None if ds.calibration is None else _calibrated_kpot(ds, notes)
    unknown_kpot = kpot is None and volts and implied_kfb is None
    if kpot is None and volts and implied_kfb is not None:
        kpot = implied_kfb
        notes.append("no calibration file: Kpot taken from the recorded controller output u")
    elif unknown_kpot and kq is not None:  # Kpot from the runs' loop gain over Kq, below
        notes.append("no calibration file and no u column: Kpot taken as the runs' loop gain over the flow test's Kq "
                     "(so the loop gain cannot show viscous friction)")
    elif unknown_kpot:
        notes.append("no calibration file and no u column: Kpot set to 1 V/in; only Kpot·Kq is identified")
    kpot = 1.0 if kpot is None else kpot
    notes += flow_notes
    typical = _given_params(ds, RATED_FLOW / ds.given["i_max"] if kq is None else kq, kpot, TYPICAL["beta_over_Vt"],
                            TYPICAL["Kce"])
    osc, start = _oscillation(runs, typical)
    span = LOG_SPAN if osc is None else OSC_SPAN
    p = fit_loop(runs, osc or typical, fit_kq=kq is None or unknown_kpot, bv_span=span)
    from_flow = unknown_kpot and kq is not None
    if from_flow:
        # the runs give the loop gain Kpot·Kq, the flow test Kq: Kpot is their ratio, which also puts the DAC's ±10 V
        # limit (on Kp·Kpot·e) where the rig has it; the runs' linear parts end there, so the loop is refitted once
        p = _kpot_from_loop_gain(fit_loop(runs, _kpot_from_loop_gain(p, kq), fit_kq=True, bv_span=span), kq)
    return Baseline(p, "runs", f"linear loop fitted to the runs, starting from the {start}", tuple(notes),
                    kpot_from_flow_test=from_flow)


def choose(ds: Dataset, runs: Sequence[GapRun], *, key: str | Path | None, implied_kfb: float | None) -> Baseline:
    """The baseline by preference: key, the students' identification, the runs."""
    why_not = None
    if key is not None:
        keyed = from_key(key, ds)
        if isinstance(keyed, Baseline):
            return keyed
        why_not = keyed
    elif ds.calibration is not None and ds.flow_test is not None and ds.friction is not None:
        try:
            ident = identify(ds)
            if ident.params is not None:
                return Baseline(_as_written(ident.params.with_(sample_time=ds.given["sample_time"])), "identified",
                                "the students' identification (flow test, calibration, friction data, instability run)")
            why_not = f"students' identification gives no model: {ident.estimates['Kce'].reason}"
        except GraderError as exc:  # e.g. a friction test whose slope B is clearly negative
            why_not = f"students' identification failed: {exc}"
    base = from_runs(ds, runs, implied_kfb)
    base = replace(base, params=_as_written(base.params))
    return base if why_not is None else replace(base, notes=(why_not, *base.notes))


def _as_written(p: RigParams) -> RigParams:
    """``p`` with its identified values at :data:`~grader.precision.SIGNIFICANT_DIGITS`, as diagnosis.json writes
    them: the search starts from the same numbers on any CPU (identification leaves last-digit differences between
    BLAS kernels, which the search's flat valleys would amplify)."""
    return p.with_(**{name: round_sig(float(getattr(p, name))) for name in _IDENTIFIED})

