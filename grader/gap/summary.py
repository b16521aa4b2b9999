"""A short plain-language summary of a diagnosis, for the terminal and the report.

Three answers, one paragraph each: where the linear model and the rig disagree, which
unmodelled effect causes it, and how much better the model gets with it.
"""

from __future__ import annotations

from grader.gap.schema import TIE_TO_COULOMB, Candidate, Diagnosis, ReadOff, ReplayInfo, RunGap, Value
from grader.gap.separating import would
from grader.units import ureg

#: Units shown to students instead of the internal ones, and how they are written.
DISPLAY = {"s": "ms"}
LABELS = {"psi/in**3": "psi/in³", "in**3/s/psi": "in³/s/psi", "in**3/s/mA": "in³/s/mA", "lbf*s/in": "lbf·s/in",
          "dimensionless": "", "%": "%"}
#: Below these a read-off value is shown as 0 (finer than any plot shows).
RESOLUTION = {"in": 1e-5, "%": 0.005, "Hz": 0.005}
NAMES = {"beta_over_Vt": "β/Vt"}
READOFF_NAMES = {"steady_state_error": "steady-state error", "overshoot": "overshoot",
                 "oscillation_frequency": "oscillation frequency", "critical_gain": "critical gain"}
SEGMENT_NAMES = {"rise": "the rise", "overshoot": "the overshoot", "settling": "settling",
                 "steady_state": "steady state", "tracking": "tracking the ramp", "oscillation": "the oscillation"}


def effect_name(effect: str) -> str:
    """``coulomb_friction`` -> ``Coulomb friction``; ``a+b`` -> ``a + b``."""
    text = effect.replace("_", " ").replace("+", " + ")
    return text.replace("coulomb", "Coulomb") if text != "none" else "no effect"


def _display(value: float, unit: str) -> tuple[float, str]:
    """(value, label) in the student-friendly unit, e.g. 0.0015 s -> (1.5, " ms")."""
    target = DISPLAY.get(unit, unit)
    v = float(ureg.Quantity(value, unit).to(target).magnitude) if target != unit else value
    label = LABELS.get(target, f"{ureg.Unit(target):~P}")
    return v, (f" {label}" if label else "")


def show(value: float, unit: str, digits: int = 3) -> str:
    """A value in a student-friendly unit, e.g. 0.0015 s -> ``1.5 ms``; values below the unit's
    read-off resolution show as 0."""
    v, label = _display(value, unit)
    if abs(v) < RESOLUTION.get(unit, 0.0):
        v = 0.0
    return f"{v:.{digits}g}{label}"


def param_text(name: str, v: Value) -> str:
    """``Fc = 4.2 ± 0.3 lbf`` (± half the 95 % interval), or ``tau = 1.63 ms (95 %: 0.1 to 3.89 ms)`` where the
    interval is lopsided about the value (its two sides differ by more than a fifth of its half-width: a bound or a log-scale
    interval); a combination's ``effect.param`` reads ``Coulomb friction Fc``."""
    effect, _, param = name.rpartition(".")
    name = f"{effect_name(effect)} {NAMES.get(param, param)}" if effect else NAMES.get(name, name)
    value, label = _display(v.value, v.unit)
    if v.interval is None:
        return f"{name} = {value:.3g}{label}"
    lo, hi = (_display(x, v.unit)[0] for x in v.interval)
    half = (hi - lo) / 2
    if abs((hi - value) - (value - lo)) > 0.2 * half:
        return f"{name} = {value:.3g}{label} (95 %: {lo:.3g} to {hi:.3g}{label})"
    return f"{name} = {value:.3g} ± {half:.2g}{label}"


def _where(d: Diagnosis) -> str:
    worst: RunGap = max(d.gap.by_run, key=lambda g: g.nrmse / max(g.noise_nrmse, 1e-12))
    seg = max(worst.segments, key=lambda s: s.share)
    ratio = worst.nrmse / max(worst.noise_nrmse, 1e-12)
    text = (f"Where: the linear model fits the whole runs to {100 * (1 - d.gap.nrmse):.1f} % overall (whole-run NRMSE "
            f"{100 * d.gap.nrmse:.2g} %). It misses most in run {worst.run} ({ratio:.1f} × the noise level), "
            f"{100 * seg.share:.0f} % of that gap during {SEGMENT_NAMES[seg.segment]}.")
    gaps = [r for r in d.readoffs if _relative_gap(r) > 0.1]
    gaps.sort(key=_relative_gap, reverse=True)
    for r in gaps[:2]:
        text += (f" {READOFF_NAMES[r.quantity].capitalize()} in {r.run}: measured {show(r.measured or 0.0, r.unit)}, "
                 f"the linear model predicts {show(r.predicted or 0.0, r.unit)}.")
    return text


def _floor(d: Diagnosis) -> float:
    """The noise floor [in] (see :class:`grader.gap.noise.Noise`)."""
    q = d.noise.adc_step.value if d.noise.adc_step else 0.0
    return max(d.noise.sigma.value, q / 12**0.5)


def _relative_gap(r: ReadOff) -> float:
    if r.measured is None or r.predicted is None:
        return 0.0
    scale = max(abs(r.measured), abs(r.predicted), 1e-12)
    floor = {"in": 5e-4, "%": 2.0, "Hz": 0.2}.get(r.unit, 0.0)
    return 0.0 if abs(r.measured - r.predicted) < floor else abs(r.measured - r.predicted) / scale


def _quantization(d: Diagnosis) -> str:
    """One sentence on a quantising ADC that matters, or ''."""
    q = d.quantization
    if q is None or not q.matters:
        return ""
    cycle = " The step runs end in a limit cycle of a few counts." if q.limit_cycle else ""
    readoff = ("" if q.share_of_readoff is None else
               f", {100 * q.share_of_readoff:.2g} % of the smallest error read off at rest")
    return (f"The readings are quantised in steps of {show(q.adc_step.value, 'in')} ({100 * q.share_of_step:.2g} % of "
            f"the step command{readoff}; about a {q.bits:.0f}-bit ±10 V ADC).{cycle} A steady-state error can only be read "
            f"to ±{show(q.steady_state_error_band.value, 'in')}, and a P loop may settle anywhere in that band round "
            "the set-point.")


def _viscous(d: Diagnosis) -> str:
    b = d.static_evidence.get("viscous_friction", {}).get("B")
    if b is None or b.interval is None:
        lg = d.loop_gain
        if lg is None or not lg.names_viscous or lg.viscous_B.interval is None:
            return ""
        lo, hi = lg.viscous_B.interval
        alt = lg.viscous_B_larger_root
        wide = "" if alt is None else (
            f" The interval is wide because a rig with more viscous friction and less leakage, B = "
            f"{show(alt.value, 'lbf*s/in')}, gives the same closed loop.")
        return (f"The runs' loop gain is {100 * lg.deficit:.2g} % below the flow test's Kq ({lg.deficit_z:.2g} "
                f"standard errors); viscous friction B = {show(lg.viscous_B.value, 'lbf*s/in')} (95 % interval "
                f"{show(lo, 'lbf*s/in')} to {show(hi, 'lbf*s/in')}) reconciles them.{wide} In the closed loop it "
                "acts as a larger Kce and a smaller Kq, so the runs alone cannot name it; the friction test would "
                "measure it.")
    return (f"The friction test shows viscous friction B = {show(b.value, 'lbf*s/in')} (95 % interval "
            f"{show(b.interval[0], 'lbf*s/in')} to {show(b.interval[1], 'lbf*s/in')}); in the closed loop it acts "
            "almost exactly as a larger Kce, so the runs alone cannot name it.")


def _resamples(confidence: float) -> str:
    """The run-bootstrap confidence in words: a share under one half is said to be only that (with no candidate
    tied, which a verdict that wins on the whole runs can still lack in most resamples)."""
    if confidence >= 0.5:
        return f"in {100 * confidence:.0f} % of resamples of the runs it stays the answer"
    return (f"but only {100 * confidence:.0f} % of resamples of the runs keep it the answer with no candidate tied "
            "to it: a weak preference")


def _which(d: Diagnosis, best: Candidate) -> str:
    v = d.verdict
    if v.effect == "sensor_quantization":
        return f"Which effect: sensor quantization. {_quantization(d)}" + "".join(_not_named(d, e) for e in v.not_named)
    if v.effect == "none":
        text = ("Which effect: none stands out. No candidate effect explains clearly more than the measurement "
                f"noise (about {show(_floor(d), 'in')} RMS); the linear model is as good as the data allow.")
    else:
        params = ", ".join(param_text(k, p) for k, p in best.params.items())
        runner = effect_name(v.runner_up or "none")
        text = f"Which effect: {effect_name(v.effect)}{f' ({params})' if params else ''}."
        if v.margin > 0:
            text += (f" It beats the runner-up, {runner}, by a margin of {v.margin:.2g} (log ratio of held-out "
                     f"scores); {_resamples(v.confidence)}.")
        elif TIE_TO_COULOMB in v.explanation:  # a Coulomb tie the friction test broke
            why = next(part for part in v.explanation.split("; ") if TIE_TO_COULOMB in part)
            text += f" The runs alone rank it with {runner}; {why}."
        text += _replayed(d, "verdict", v.effect)
        dropped = next((r for r in d.replay if r.of == "dropped_second_effect"), None)
        if dropped is not None:  # a second effect the closed loop's bar named, not borne out by the replayed runs
            added = next(e for e in dropped.excess if e != "none")
            text += (f" {effect_name(added).capitalize()} on top fits the closed-loop runs clearly better, but not the "
                     "runs replayed through the controller output the rig recorded, so it is not named.")
    if v.indistinguishable_from:
        others = ", ".join(_with_params(d, e) for e in v.indistinguishable_from)
        text += f" The data cannot tell it apart from: {others}; {would(v.separating_test, 'separate them')}."
    if v.not_ruled_out:
        lg = d.loop_gain
        upto = "" if lg is None or lg.viscous_B.interval is None else \
            f" up to B = {show(lg.viscous_B.interval[1], 'lbf*s/in')}"
        text += (f" It cannot rule out {', '.join(effect_name(e) for e in v.not_ruled_out)}{upto} (in the closed loop "
                 f"it acts as a larger Kce); {would(v.separating_test, 'show it')}.")
    combo = combination(d)
    if v.second_effect == "viscous_friction" and combo is None or v.effect == "viscous_friction":
        text += f" {_viscous(d)}"
    if v.second_effect and combo is not None:
        params = ", ".join(param_text(k, p) for k, p in combo.params.items())
        nested = _nested(d)
        if nested is None:
            text += f" On top of it, {effect_name(v.second_effect)} explains clearly more ({params})."
        else:
            rivals = _apart(d, "second_effect", v.second_effect)
            text += (f" On top of it, {effect_name(v.second_effect)} ({params}): replayed through the controller "
                     f"output the rig recorded, the runs follow it better than {effect_name(v.effect)} alone (by "
                     f"{by_text(nested.excess['none'] - nested.excess[v.second_effect])} in 2·ln likelihood)"
                     f"{f' or with {rivals} on top instead' if rivals else ''}, though the closed-loop runs alone do "
                     "not show it.")
        if v.second_indistinguishable_from:
            others = ", ".join(effect_name(e) for e in v.second_indistinguishable_from)
            text += (f" The data cannot tell {effect_name(v.second_effect)} apart from: {others}; "
                     f"{would(v.second_separating_test, 'separate them')}.")
        if nested is None:
            text += _replayed(d, "second_effect", v.second_effect)
        beside = _apart(d, "verdict_with_second_effect", v.effect)  # lookalikes of the verdict dropped beside the pair
        if beside:
            text += (f" With {effect_name(v.second_effect)} on top, replayed through the controller output the rig "
                     f"recorded, the runs follow {effect_name(v.effect)} better than {beside}.")
    elif v.second_effect == "sensor_quantization":
        text += f" {_quantization(d)}"
    return text + "".join(_not_named(d, e) for e in v.not_named)


def _not_named(d: Diagnosis, effect: str) -> str:
    """A sentence on an effect the evidence shows and the verdict does not name (``verdict.not_named``)."""
    v, lg = d.verdict, d.loop_gain
    if effect == "viscous_friction" and "sensor_quantization" in (v.effect, v.second_effect) and lg is not None:
        return (f" The runs' loop gain is {100 * lg.deficit:.2g} % below the flow test's Kq ({lg.deficit_z:.2g} "
                f"standard errors), which viscous friction B = {show(lg.viscous_B.value, 'lbf*s/in')} would "
                "reconcile, but viscous friction is not named: the runs' fits lack the ADC, which biases their Kq. "
                "The friction test would measure it.")
    said = _quantization(d) if effect == "sensor_quantization" else _viscous(d)
    return f" A third effect, not named (a verdict names two at most): {effect_name(effect)}. {said}"


def by_text(x: float) -> str:
    """A replay's excess (2·ln likelihood) as text: three digits, a whole number with thousands separators from
    1,000 up, and "more than 100,000" beyond (a fit whose residual reached the cap that marks a diverged model)."""
    if abs(x) > 1e5:
        return "more than 100,000"
    return f"{x:,.0f}" if abs(x) >= 1000 else f"{x:.3g}"


def _percent(share: float) -> str:
    """A share (fraction) in whole percent, "under 1 %" for a share that is there but rounds to 0."""
    return "under 1 %" if 0 < share < 0.005 else f"{100 * share:.0f} %"


def _nested(d: Diagnosis) -> ReplayInfo | None:
    """The replay that named the second effect where the closed loop's bar did not (the verdict alone, ``none``
    on top, among its entries), or None."""
    return next((r for r in d.replay if r.of == "second_effect" and "none" in r.excess), None)


def _apart(d: Diagnosis, of: str, effect: str) -> str:
    """The lookalikes the replayed runs told apart from ``effect`` (the verdict or the second effect; not the
    verdict alone), worst last, each with by how much: '' where none was, or the replay decided nothing."""
    r = next((r for r in d.replay if r.of == of and r.decides and effect in r.excess), None)
    if r is None:
        return ""
    apart = sorted(((e, x - r.excess[effect]) for e, x in r.excess.items()
                    if e not in (effect, "none") and x - r.excess[effect] >= r.evidence), key=lambda a: a[1])
    worse = ", ".join(f"{effect_name(e)} (by {by_text(x)} in 2·ln likelihood)" for e, x in apart[:2])
    return worse + (f" and {len(apart) - 2} more" if len(apart) > 2 else "")


def _replayed(d: Diagnosis, of: str, effect: str) -> str:
    """The lookalikes the replayed runs told apart from ``effect``, as a sentence ('' where none was)."""
    worse = _apart(d, of, effect)
    return (f" Replayed through the controller output the rig recorded, the runs follow {effect_name(effect)} better "
            f"than {worse}." if worse else "")


def _with_params(d: Diagnosis, effect: str) -> str:
    """An effect's name with its fitted parameters, as its candidate gives them (a second-order spool: ``tau = 2.5
    ± 0.13 ms, order = 2, zeta = 0.7``)."""
    c = next((c for c in d.candidates if c.effect == effect), None)
    params = "" if c is None else ", ".join(param_text(k, p) for k, p in c.params.items())
    return f"{effect_name(effect)} ({params})" if params else effect_name(effect)


def combination(d: Diagnosis) -> Candidate | None:
    """The candidate with the verdict's second effect added, if the diagnosis has one."""
    pair = {d.verdict.effect, d.verdict.second_effect}
    return next((c for c in d.candidates if "+" in c.effect and set(c.effect.split("+")) == pair), None)


def _how_far(d: Diagnosis, best: Candidate) -> str:
    if d.verdict.effect == "sensor_quantization":
        return ("How far it shrinks: the ADC is a measurement effect; no model of the rig fits the readings "
                f"closer than its steps allow (held-out NRMSE of the re-fitted linear model "
                f"{100 * best.heldout_nrmse_before:.2g} %).")
    if d.verdict.effect == "none":
        return (f"How far it shrinks: nothing to add. The re-fitted linear model predicts a typical left-out run "
                f"with an NRMSE of {100 * best.heldout_nrmse_before:.2g} %.")
    if best.effect == "none":  # named from the static tests, not from the runs
        return (f"How far it shrinks: not measurable from the runs, which take {effect_name(d.verdict.effect)} for "
                f"re-fitted linear parameters: the re-fitted linear model predicts a typical left-out run with an "
                f"NRMSE of {100 * best.heldout_nrmse_before:.2g} %.")
    text = (f"How far it shrinks: adding {effect_name(best.effect)} to the model removes "
            f"{100 * best.shrink:.0f} % of the gap on a typical run left out of the fit (NRMSE "
            f"{100 * best.heldout_nrmse_before:.2g} % → {100 * best.heldout_nrmse_after:.2g} %, geometric mean over runs).")
    combo = combination(d)
    if combo is not None:
        shares = " and ".join(f"{effect_name(k)} {_percent(v)}" for k, v in d.verdict.shares.items())
        of = ("of what the pair explains of the replayed runs' sum of squares" if _nested(d) is not None else
              "of that shrink")
        text += (f" With {effect_name(d.verdict.second_effect or '')} too: {100 * combo.shrink:.0f} % "
                 f"(shares {of}: {shares}).")
    return text


def summary(d: Diagnosis) -> str:
    """The plain-language summary (a few short paragraphs)."""
    best = d.candidates[0]
    head = f"Sim-to-real diagnosis of {d.dataset} (station {d.station}; linear model: {d.baseline.method})."
    return "\n\n".join([head, _where(d), _which(d, best), _how_far(d, best)])
