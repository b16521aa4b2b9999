"""The valve's null current in the runs, read where the runs rest.

A servo valve's null is never exactly at zero current. Closed, the loop rests where the valve passes no
flow: a P or PD loop with its position off the command by δ = i0/(Kamp·Kp·k_fb), a PI loop with its
integrator holding −i0/Kamp, so that the controller output u rests at −i0/Kamp [V] in every run. A model
started at rest at the command with no current lacks it, and the P runs' steady-state errors then differ
from the rig's by δ ∝ 1/Kp: on an independent simulator's rigs with no effect, nulls of 0.005 and 0.017 mA
were named Coulomb friction and viscous friction (a loop-gain deficit of 3.1 standard errors), and nulls of
±0.1 and 0.3 mA had 6 of 12 such rigs named Coulomb friction, a deadband, hysteresis or a current limit.

A run rests before its command, and a P or PD step run again over the last :data:`END_SHARE` of its samples
(an instability run, at its critical gain, never rests). Each rest of at least :data:`MIN_REST` samples whose
halves agree (within :data:`SETTLING_Z` standard errors: else the rig is still settling) gives i0:
−Kamp·mean(u) where u is recorded, else (a P or PD run) Kamp·Kp·k_fb·mean(y − r), with the standard error of a
mean of AR(1) samples. Their inverse-variance mean is the rig's null where it lies :data:`NULL_Z` standard
errors or more from 0 and the rests agree on it (χ² of their spread below its :data:`AGREE` quantile). Friction
holds a rig wherever its last motion stopped, on the side it came from: a step run that rests on one side
before its command and on the other after it disagrees with itself, which a null cannot do. The model then has
the null in every run (:attr:`GapRun.null_u`, :attr:`GapRun.command_shift`), and a note says so. Quantised
readings at rest average to up to half a lattice step off where the rig rests, so a null that holds no P or
PD run half a step off its command is none.
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
                "and trimming the valve's null removes it")


def _mean_se(x: np.ndarray) -> tuple[float, float]:
    """Mean of ``x`` and its standard error, inflated for lag-1 autocorrelation."""
    d = x - x.mean()
    var = float(d @ d) / max(x.size - 1, 1)
    rho = float(d[1:] @ d[:-1]) / float(d @ d) if float(d @ d) > 0 else 0.0
    rho = min(max(rho, 0.0), MAX_RHO)
    return float(x.mean()), float(np.sqrt(var / x.size * (1.0 + rho) / (1.0 - rho)))


def _reading(run: GapRun, at: np.ndarray, Kamp: float, k_fb: float | None) -> tuple[float, float] | None:
    """(i0, standard error) [mA] from the samples ``at`` where the run rests, or None where they give none."""
    if int(at.sum()) < MIN_REST:
        return None
    if run.u is not None:
        x, gain = run.u[at], -Kamp
    elif run.controller.Ki != 0.0 or k_fb is None:
        return None
    else:
        x, gain = run.y[at] - run.r[at], Kamp * run.controller.Kp * k_fb
    (m1, s1), (m2, s2) = _mean_se(x[: x.size // 2]), _mean_se(x[x.size // 2:])
    if abs(m2 - m1) > SETTLING_Z * math.hypot(s1, s2):  # still settling: no rest
        return None
    m, se = _mean_se(x)
    return gain * m, abs(gain) * se


def _rests(run: GapRun) -> list[tuple[str, np.ndarray]]:
    """Where ``run`` rests: before its command, and a P or PD step run also over its last :data:`END_SHARE` (an
    instability run, at its critical gain, never rests)."""
    if run.kind == "instability":
        return []
    out = [(f"{run.name} before its command", run.t < run.start)]
    if run.kind == "step" and run.controller.Ki == 0.0:
        after = np.flatnonzero(run.t >= run.start)
        end = np.zeros(run.t.size, dtype=bool)
        end[after[int((1.0 - END_SHARE) * after.size):]] = True
        out.append((f"{run.name} at its end", end))
    return out


def estimate(runs: Sequence[GapRun], Kamp: float, k_fb: float | None, step: float = 0.0) -> Null | None:
    """The rig's null (module docstring), or None where the runs show none; ``Kamp`` [mA/V], ``k_fb`` [V/in] or
    1 (None: not known, so only runs with u give it). ``step`` [in]: the readings' lattice step, if quantised; a
    null that holds no P or PD run at least half a step off its command is below what the readings resolve (the
    mean of quantised readings at rest is off by up to half a step)."""
    read = [(name, v) for r in runs for name, at in _rests(r) for v in [_reading(r, at, Kamp, k_fb)]
            if v is not None and v[1] > 0.0]
    if not read:
        return None
    i0s, ses = np.array([v[0] for _, v in read]), np.array([v[1] for _, v in read])
    w = 1.0 / ses**2
    i0, se = float(np.sum(w * i0s) / np.sum(w)), float(1.0 / np.sqrt(np.sum(w)))
    spread = float(np.sum(w * (i0s - i0) ** 2))
    if abs(i0) < NULL_Z * se or (len(read) > 1 and spread > stats.chi2.ppf(AGREE, len(read) - 1)):
        return None
    p_gains = [r.controller.Kp for r in runs if r.controller.Ki == 0.0 and r.controller.Kp > 0.0]
    if step > 0.0 and k_fb and p_gains and abs(i0) < Kamp * min(p_gains) * k_fb * step / 2.0:
        return None
    return Null(i0, se, tuple(name for name, _ in read))


def held(runs: Sequence[GapRun], null: Null | None, Kamp: float, k_fb: float) -> list[GapRun]:
    """The runs with the null in them: u shifted by i0/Kamp [V] where replayed, and the command of a P or PD run by
    δ = i0/(Kamp·Kp·k_fb) [in] (a PI loop's integrator holds it: no shift)."""
    if null is None:
        return list(runs)
    u0 = null.i0 / Kamp
    return [replace(r, null_u=u0, command_shift=u0 / (r.controller.Kp * k_fb)
                    if r.controller.Ki == 0.0 and r.controller.Kp * k_fb != 0.0 else 0.0) for r in runs]
