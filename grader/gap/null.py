"""The valve's null current in the runs, read where the runs rest.

A servo valve's null is never exactly at zero current: it passes no flow at some current i0 [mA] (the flow
test's null offset, in the same sense). Closed, the loop rests there: a P or PD loop with its position off the
command by i0/(Kamp·Kp·k_fb) (the controller output at rest is then i0/Kamp), a PI loop with its integrator
holding i0/Kamp. A model started at rest at the command with no current lacks it, and the P runs'
steady-state errors then differ from the rig's by an amount ∝ 1/Kp: on an independent simulator's rigs with no
effect, nulls of 0.005 and 0.017 mA were named Coulomb friction and viscous friction (a loop-gain deficit of 3.1
standard errors), and nulls of 0.1 mA either way and of 0.3 mA had 6 of 12 such rigs named Coulomb friction, a
deadband, hysteresis or a current limit.

A run rests before its command, and a P or PD step run again over the last :data:`END_SHARE` of its samples where
its command holds still. An instability run's rests are not read: at its critical gain the loop is so lightly
damped that its readings at rest wander far from AR(1) noise, and their standard error is not to be trusted.
Each rest of at least :data:`MIN_REST` samples whose halves agree (within :data:`SETTLING_Z` standard errors: else
the rig is still settling) gives i0: Kamp·mean(u) where u is recorded, else (a P or PD run)
−Kamp·Kp·k_fb·mean(y − r), with the standard error of a mean of AR(1) samples, at least that of the readings'
lattice (step/√12). Their inverse-variance mean is the rig's null where it lies :data:`NULL_Z` standard errors or
more from 0 and the rests agree on it (χ² of their spread below its :data:`AGREE` quantile). Friction holds a
rig wherever its last motion stopped, on the side it came from: a step run that rests on one side before its
command and on the other after it disagrees with itself, which a null cannot do. Quantised readings at rest
average to up to half a lattice step off where the rig rests, so a null that holds no P or PD run half a step
off its command is none. The model then has the null in every run (:attr:`GapRun.null_u`,
:attr:`GapRun.command_shift`: exact while neither the DAC nor a current limit clips, where the model clips the
shifted signal rather than the amplifier's own), and a note says so.

Where the rests disagree, so that none is read, but a rest before a command lies :data:`FREE_Z` standard errors or
more off 0 (a rig resting at its command has nothing but its noise to move it until the command changes), friction,
a deadband or hysteresis holds the rig somewhere in a band around a null: :func:`free` then has the null fitted
with every candidate (:meth:`grader.gap.candidates.Candidate.with_null`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from grader.gap.runs import GapRun
from grader.identify.estimate import Z95

#: Least samples of a rest that gives the null (each half of it is checked for settling).
MIN_REST = 20
#: Standard errors from 0 from which the null is the rig's.
NULL_Z = 3.0
#: Quantile of χ² below which the runs' estimates agree.
AGREE = 0.99
#: Most lag-1 autocorrelation taken for the rest's samples (the variance of their mean inflates by (1 + ρ)/(1 − ρ)).
MAX_RHO = 0.9
#: Share of a P or PD step run's samples after its command, at its end, read as a second rest.
END_SHARE = 0.2
#: Standard errors by which a rest's two halves may differ before it is taken for a rig still settling.
SETTLING_Z = 3.0
#: Standard errors off 0 from which some rest before a command shows a null that friction hides (:func:`free`): a
#: two-sided p of 6e-5 per rest, under 0.1 % over ten rests (Bonferroni), since any of a dataset's may show it. Rigs
#: with friction and no null read up to 3.5 there (the AR(1) standard error understates a rig held by friction while
#: its noise nudges it), rigs with a null from 4.5 up.
FREE_Z = 4.0


@dataclass(frozen=True)
class Null:
    """The null current ``i0`` [mA], its standard error [mA], and the rests it was read in."""

    i0: float
    se: float
    rests: tuple[str, ...]

    def interval(self) -> tuple[float, float]:
        """The 95 % interval of i0 [mA] (normal)."""
        return self.i0 - Z95 * self.se, self.i0 + Z95 * self.se

    def text(self) -> str:
        """One sentence for the notes."""
        lo, hi = self.interval()
        return (f"the valve passes no flow at {self.i0:.3g} mA, not at 0 (its null; 95 % interval {lo:.3g} to {hi:.3g} "
                f"mA, read where the runs rest: {', '.join(self.rests)}): a P loop rests off its command by "
                "i0/(Kamp·Kp·k_fb) and a PI loop holds it with its integrator; every model here has it in every run, "
                "and trimming the valve's null would remove it")


def fitted_text(i0: float, interval: tuple[float, float], effect: str) -> str:
    """The note on a null fitted with every candidate (:func:`free`), as the fit with ``effect`` (the augmented
    model's, named for the reader) puts it: no flow at ``i0`` [mA] within ``interval``."""
    lo, hi = interval
    where = (f"the fit with {effect} puts its null at {i0:.3g} mA (95 % interval {lo:.3g} to {hi:.3g} mA)"
             + (", not at 0" if lo > 0 or hi < 0 else ", which 0 lies within"))
    return ("before the commands change, the runs rest off them, as a valve passing flow at zero current would hold "
            "them, but the rests disagree on how far (friction, a deadband or hysteresis holds a rig anywhere in a band "
            f"around its null): so every model here fits the valve's null with its effect, and {where}")


def _mean_se(x: np.ndarray, floor: float = 0.0) -> tuple[float, float]:
    """Mean of ``x`` and its standard error, inflated for lag-1 autocorrelation and at least ``floor`` (samples
    all equal have no spread: not the round-off of subtracting their mean)."""
    if float(np.ptp(x)) == 0.0:
        return float(x[0]), floor
    d = x - x.mean()
    ss = float(d @ d)
    rho = min(max(float(d[1:] @ d[:-1]) / ss, 0.0), MAX_RHO) if ss > 0 else 0.0
    se = math.sqrt(ss / max(x.size - 1, 1) / x.size * (1.0 + rho) / (1.0 - rho))
    return float(x.mean()), max(se, floor)


def _reading(run: GapRun, at: np.ndarray, Kamp: float, k_fb: float, step: float) -> tuple[float, float] | None:
    """(i0, standard error) [mA] from the samples ``at`` where the run rests (``step`` [in]: the readings' lattice,
    0 if none), or None where they give none."""
    if run.u is not None:
        at = at & np.isfinite(run.u)
    if int(at.sum()) < MIN_REST:
        return None
    if run.u is not None:
        x, gain, lattice = run.u[at], Kamp, step * abs(run.controller.Kp) * k_fb
    elif run.controller.Ki != 0.0:
        return None
    else:
        x, gain, lattice = run.y[at] - run.r[at], -Kamp * run.controller.Kp * k_fb, step
    floor = lattice / math.sqrt(12.0)
    (m1, s1), (m2, s2) = _mean_se(x[: x.size // 2], floor), _mean_se(x[x.size // 2:], floor)
    if abs(m2 - m1) > SETTLING_Z * math.hypot(s1, s2):  # still settling: no rest
        return None
    m, se = _mean_se(x, floor)
    return (gain * m, abs(gain) * se) if se > 0.0 else None  # constant readings of unknown resolution: no reading


def _rests(run: GapRun) -> list[tuple[str, np.ndarray, bool]]:
    """Where ``run`` rests (module docstring), and whether before its command: before its command, and a P or PD
    step run also over its last :data:`END_SHARE` where its command holds still."""
    if run.kind == "instability":
        return []
    out = [(f"{run.name} before its command", run.t < run.start, True)]
    if run.kind == "step" and run.controller.Ki == 0.0:
        after = np.flatnonzero(run.t >= run.start)
        end = np.zeros(run.t.size, dtype=bool)
        end[after[int((1.0 - END_SHARE) * after.size):]] = True
        if end.any() and float(np.ptp(run.r[end])) == 0.0:
            out.append((f"{run.name} at its end", end, False))
    return out


def _readings(runs: Sequence[GapRun], Kamp: float, k_fb: float, step: float) -> list[tuple[str, bool, float, float]]:
    """(rest, whether before a command, i0, its standard error [mA]) of each rest that gives a reading."""
    return [(name, before, *v) for r in runs for name, at, before in _rests(r)
            for v in [_reading(r, at, Kamp, k_fb, step)] if v is not None]


def _pooled(read: Sequence[tuple[str, bool, float, float]]) -> tuple[float, float, bool]:
    """The readings' inverse-variance mean i0 and its standard error [mA], and whether they agree on it (χ² of their
    spread below its :data:`AGREE` quantile; a single reading agrees with itself)."""
    i0s, ses = np.array([v[2] for v in read]), np.array([v[3] for v in read])
    w = 1.0 / ses**2
    i0, se = float(np.sum(w * i0s) / np.sum(w)), float(1.0 / np.sqrt(np.sum(w)))
    spread = float(np.sum(w * (i0s - i0) ** 2))
    return i0, se, len(read) < 2 or spread <= stats.chi2.ppf(AGREE, len(read) - 1)


def estimate(runs: Sequence[GapRun], Kamp: float, k_fb: float | None, step: float = 0.0) -> Null | None:
    """The rig's null (module docstring), or None where the runs show none; ``Kamp`` [mA/V], ``k_fb`` [V/in] or 1
    (None: not known, and no null is read), ``step`` [in]: the readings' lattice step, if quantised."""
    if k_fb is None:
        return None
    read = _readings(runs, Kamp, k_fb, step)
    if not read:
        return None
    i0, se, agree = _pooled(read)
    if abs(i0) < NULL_Z * se or not agree:
        return None
    p_gains = [r.controller.Kp for r in runs if r.controller.Ki == 0.0 and r.controller.Kp > 0.0]
    if step > 0.0 and p_gains and abs(i0) < Kamp * min(p_gains) * k_fb * step / 2.0:
        return None
    return Null(i0, se, tuple(v[0] for v in read))


def free(runs: Sequence[GapRun], Kamp: float, k_fb: float | None, step: float = 0.0) -> float | None:
    """Where the runs hold a null that friction hides, the unit [mA] in which to fit it with every candidate
    (:attr:`~grader.gap.candidates.Candidate.null_scale`: the largest current a rest reads), else None. Called where
    :func:`estimate` reads none. A rig at rest at its command has nothing but its noise to move it before the
    command changes, unless its valve passes flow there: a rest before a command that reads a current
    :data:`FREE_Z` standard errors or more from 0 shows a null, and rests that disagree on it (beyond their
    :data:`AGREE` quantile) show a rig held wherever its last motion stopped, within a band around the null
    (Coulomb friction, a deadband, hysteresis). Their spread is no standard error of the null: the fit of each
    candidate, which moves the rig through each run's history, reads it instead."""
    if not k_fb or not any(r.controller.Ki == 0.0 and r.controller.Kp != 0.0 for r in runs):
        return None  # no P or PD run: every loop's integrator holds the null, and no run shows it
    read = _readings(runs, Kamp, k_fb, step)
    if not any(before and abs(i) >= FREE_Z * se for _, before, i, se in read) or _pooled(read)[2]:
        return None
    return max(abs(v[2]) for v in read)


def held(runs: Sequence[GapRun], null: Null | None, Kamp: float, k_fb: float | None) -> list[GapRun]:
    """The runs with the null in the model's inputs: the valve sees Kamp·u − i0, so a replayed u is shifted by
    −i0/Kamp [V], and a P or PD run's command by −i0/(Kamp·Kp·k_fb) [in] (a PI loop's integrator holds it: no
    shift)."""
    if null is None or not k_fb:
        return list(runs)
    u0 = -null.i0 / Kamp
    return [replace(r, null_u=u0, null_offset=u0 / k_fb) for r in runs]
