"""Does a quantising ADC matter? The sensor_quantization verdict.

The noise floor (:mod:`grader.gap.noise`) finds the readings' lattice step q [in]. It matters
to the students when q is at least :data:`STEP_SHARE` of the step command or, where the reading noise
does not dither it (below), of the smallest error they read off at rest, at the end of a run whose
command moves less than :data:`SWEEP` counts there (a steady-state error is then read off in counts of
q; dithered, or swept across the lattice by a moving command, the readings averaged over the run's end
resolve the error below q: docs/explanation/diagnosis.md#quantisation gives the boards that were named
otherwise where they mattered to nothing), or when the readings at the end of a step run hold a limit
cycle of a few counts that noise does not explain (white-noise RMS below :data:`QUIET` q). Then the
diagnosis names ``sensor_quantization``, estimates the bits of a ±10 V board from q and the pot gain
Kpot (LSB = q·Kpot = 20 V / 2**bits) and states what it does to the steady-state error: with a P loop
the position may settle anywhere in the ±q/2 band round the set-point that reads as zero error.

A lattice whose step is a power of ten in a length unit (0.0001 in, 0.001 mm), with the readings
on it, is the precision the file was printed with, not an ADC (a ±10 V board's step through a pot
is a decimal step by chance only). Where the reading noise dithers it (white-noise RMS at least
:data:`DITHER` q: the quantiser's mean is then linear to within 1 %, so averaging the readings
resolves errors below q), it matters to nothing and stays a note; printed coarser than the noise,
the readings students read are quantised all the same, and the rules above apply.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from grader.gap.noise import Noise
from grader.gap.runs import GapRun
from grader.model.effects import EFFECTS

QUANTIZATION = "sensor_quantization"
STEP_SHARE = 0.01
QUIET = 0.3
LIMIT_CYCLE_COUNTS = (1, 4)  # peak-to-peak readings, in counts, of a quantisation limit cycle
TAIL = 0.3  # [s] end of a step run examined for a limit cycle
#: Counts of q a command must move over a run's last TAIL for its error read off to be no error at rest: swept
#: across that many counts, the readings' rounding averages out of the error to within q/(2·SWEEP) (generically;
#: this lab's ramps move about 200 counts there).
SWEEP = 10
ADC_SPAN = 20.0  # [V] a ±10 V board
#: White-noise RMS, in steps q, from which the noise dithers a lattice: exp(−2π²·DITHER²) < 1 % (Widrow's bound).
DITHER = 0.5
#: Inches to the length units a file may be printed in (in, mm, cm, m), and the tolerance of a decimal step (a
#: printed one is exact; the lattice step is read to 1e-9 in); a step within WHOLE_BITS of a whole number of bits of
#: a ±10 V board through the calibrated Kpot is an ADC's, decimal or not.
PRINT_UNITS, DECIMAL_TOL, WHOLE_BITS = (1.0, 25.4, 2.54, 0.0254), 1e-3, 0.01


@dataclass(frozen=True)
class Quantization:
    """The ADC's step q [in], its share of the step command and of the smallest error read off at rest (nan: none
    read off), the estimated bits and whether it matters."""

    step: float
    share: float
    bits: float
    limit_cycle: bool
    readoff_share: float = float("nan")
    #: the lattice is the file's print precision, finer than the reading noise (module docstring)
    printed: bool = False
    #: the reading noise dithers the lattice (module docstring): an error read off a run's end resolves below q
    dithered: bool = False

    @property
    def matters(self) -> bool:
        if self.printed:
            return False
        readoff = self.readoff_share >= STEP_SHARE and not self.dithered
        return self.share >= STEP_SHARE or readoff or self.limit_cycle

    def text(self) -> str:
        """One sentence for the notes or the verdict."""
        readoff = (f", {100 * self.readoff_share:.2g} % of the smallest error read off at rest"
                   if self.readoff_share == self.readoff_share else "")
        core = (f"the readings are quantised in steps of {self.step:.3g} in ({100 * self.share:.2g} % of the step "
                f"command{readoff}; about a {self.bits:.0f}-bit ±10 V ADC)")
        if self.printed:
            return (f"the readings are printed in steps of {self.step:.3g} in, finer than their noise: the file's print "
                    "precision, not an ADC, and part of the noise floor")
        if not self.matters:
            dither = (": the reading noise dithers it, so an error averaged over a run's end resolves below one step"
                      if self.dithered and self.readoff_share >= STEP_SHARE else "")
            return f"{core}{dither}: part of the noise floor"
        cycle = "; the step runs end in a limit cycle of a few counts" if self.limit_cycle else ""
        return (f"{core}{cycle}: a steady-state error is read to ±{self.step / 2:.3g} in at best, and a P loop "
                f"may settle anywhere within ±{self.step / 2:.3g} in of the set-point")


#: An ADC's estimated bits within this of a whole number are simulated in the augmented model's loop.
LOOP_BITS_TOL = 0.05


def loop_bits(bits: float) -> int | None:
    """The whole number of bits of a ±10 V board to simulate for an estimate of ``bits``, or None where it is not
    within :data:`LOOP_BITS_TOL` of one (another span, or no ADC's step) or outside the simulator's range."""
    spec = EFFECTS[QUANTIZATION].param("bits")
    if not math.isfinite(bits) or not spec.lo <= round(bits) <= spec.hi or abs(bits - round(bits)) >= LOOP_BITS_TOL:
        return None
    return int(round(bits))


class _Named(Protocol):
    effect: str
    second_effect: str | None


class _Assessed(Protocol):
    bits: float
    matters: bool


def loop_adc(quant: _Assessed | None, verdict: _Named) -> int | None:
    """The bits of the ADC the augmented model has in its loop: where the verdict names ``sensor_quantization``
    (as the verdict or its second effect), the ADC matters, and its step is whole bits (:func:`loop_bits`); else
    None. One rule for the simulation (:mod:`grader.gap.diagnose`) and its label (:mod:`grader.gap.report`);
    ``quant`` is a :class:`Quantization` or the report's ``QuantizationInfo``."""
    if quant is None or not quant.matters or QUANTIZATION not in (verdict.effect, verdict.second_effect):
        return None
    return loop_bits(quant.bits)


def _limit_cycle(run: GapRun, q: float, sigma: float) -> bool:
    tail = run.y[run.t >= run.t[-1] - TAIL]
    counts = round(float(np.ptp(tail)) / q)
    return sigma < QUIET * q and LIMIT_CYCLE_COUNTS[0] <= counts <= LIMIT_CYCLE_COUNTS[1] and np.unique(tail).size > 1


def _readoff_error(runs: Sequence[GapRun], q: float, sigma: float) -> float:
    """The smallest error students read off at rest [in]: |command − reading| averaged over the last :data:`TAIL`
    of each step and ramp run whose command moves less than :data:`SWEEP` counts of q there (a moving command
    sweeps the readings across the lattice, whose rounding averages out), counting only errors clearly above zero
    (over q and 3 σ); nan if none."""
    errors = [abs(float(np.mean(r.r[tail] - r.y[tail]))) for r in runs if r.kind in ("step", "ramp")
              for tail in [r.t >= r.t[-1] - TAIL] if float(np.ptp(r.r[tail])) < SWEEP * q]
    clear = [e for e in errors if e > max(q, 3.0 * sigma)]
    return min(clear) if clear else float("nan")


def _printed(runs: Sequence[GapRun], q: float, sigma: float, bits: float) -> bool:
    """Whether the lattice of step ``q`` [in] is a print precision the noise dithers (module docstring): q a power
    of ten in one of :data:`PRINT_UNITS` and not a whole number of ``bits`` (:data:`WHOLE_BITS`), 95 % of the
    readings on multiples of it, and the white noise (the RMS ``sigma`` less the lattice's own q/√12) at least
    :data:`DITHER` q."""
    decimal = any(abs(q * f / 10.0 ** round(math.log10(q * f)) - 1.0) < DECIMAL_TOL for f in PRINT_UNITS)
    if not decimal or (math.isfinite(bits) and abs(bits - round(bits)) < WHOLE_BITS):
        return False
    y = np.concatenate([r.y for r in runs]) / q
    on = float(np.mean(np.abs(y - np.round(y)) < 0.02))
    return on >= 0.95 and dithers(q, sigma)


def dithers(q: float, sigma: float) -> bool:
    """Whether white noise dithers a lattice of step ``q`` [in]: the readings' RMS ``sigma`` [in] less the lattice's
    own q/√12 at least :data:`DITHER` q."""
    return sigma**2 - q**2 / 12.0 >= (DITHER * q) ** 2


def assess(runs: Sequence[GapRun], noise: Noise, kpot: float) -> Quantization | None:
    """The ADC's effect, if the readings are quantised (see module docstring); ``kpot`` [V/in]."""
    q = noise.adc_step
    if q is None:
        return None
    steps = [r for r in runs if r.kind == "step"] or list(runs)
    command = max(float(np.ptp(r.r)) for r in steps) or 1.0
    bits = math.log2(ADC_SPAN / (q * kpot)) if q * kpot > 0 else float("nan")
    white = noise.sigma
    return Quantization(q, q / command, bits, any(_limit_cycle(r, q, white) for r in steps),
                        q / _readoff_error(runs, q, white), _printed(runs, q, white, bits), dithers(q, white))
