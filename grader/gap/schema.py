"""The ``diagnosis.json`` schema (pydantic), stable across versions of ``grader.diagnosis/1``.

Top level: ``schema``, ``dataset``, ``station``, ``inputs_sha256``, ``generated_by``,
``baseline`` (the linear model compared against), ``noise`` (the noise floor),
``gap`` (where the linear model and the rig disagree, per run and segment),
``readoffs`` (the quantities students read off, measured vs predicted),
``candidates`` (the verdict first, then by score: effect, fitted parameters with units and 95 % intervals (none for a held one),
held-out NRMSE before and after, shrink), ``verdict`` and ``notes``.
Fit measure: NRMSE = ‖y − ŷ‖ / ‖y − mean(y)‖ per run; ``fit_percent`` = 100·(1 − NRMSE),
the fit of MATLAB's ``compare``. Overall fit values (``gap.nrmse``, ``fit_nrmse``) are the
root-mean-square over runs; overall held-out values (``heldout_nrmse_*``, ``shrink``) the
geometric mean over runs, the typical run, which one unpredictable run cannot swamp.
"""

from __future__ import annotations

import json
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


SCHEMA = "grader.diagnosis/1"
SegmentName = Literal["rise", "overshoot", "settling", "steady_state", "tracking", "oscillation"]


class _Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Value(_Frozen):
    """A number with its unit and optional 95 % interval."""

    value: float
    unit: str
    interval: tuple[float, float] | None = None


class BaselineModel(_Frozen):
    """The linear model the data are compared with, and where it came from."""

    source: Literal["key", "identified", "runs"]
    method: str
    params: dict[str, Value]


class NoiseFloor(_Frozen):
    """Measurement noise as estimated from the runs."""

    sigma: Value = Field(description="RMS reading noise, white noise and ADC quantisation together")
    adc_step: Value | None = Field(None, description="position step of a quantising ADC, if the readings show one")
    method: str


class SegmentGap(_Frozen):
    segment: SegmentName
    t_start: float = Field(description="s")
    t_end: float = Field(description="s")
    samples: int
    share: float = Field(ge=0, le=1, description="share of the run's squared residual")
    rms_residual: float = Field(description="in")


class RunGap(_Frozen):
    run: str
    kind: Literal["step", "ramp", "instability"]
    nrmse: float = Field(ge=0)
    fit_percent: float
    rms_residual: float = Field(description="in")
    noise_nrmse: float = Field(ge=0, description="NRMSE the noise alone would give")
    segments: list[SegmentGap]


class Gap(_Frozen):
    nrmse: float = Field(ge=0, description="RMS over runs of the per-run NRMSE")
    by_run: list[RunGap]


class ReadOff(_Frozen):
    """A quantity students read off a plot: measured vs predicted by the linear and augmented models."""

    quantity: Literal["steady_state_error", "overshoot", "oscillation_frequency", "critical_gain"]
    run: str
    unit: str
    measured: float | None
    predicted: float | None
    augmented: float | None = None


class RunShrink(_Frozen):
    run: str
    heldout_nrmse_before: float
    heldout_nrmse_after: float
    shrink: float


class Candidate(_Frozen):
    """One candidate effect, fitted with β/Vt, Kce and Kq, scored by leave-one-run-out cross-validation."""

    effect: str
    params: dict[str, Value]
    linear_params: dict[str, Value] = Field(description="β/Vt, Kce and Kq (the loop gain) re-fitted jointly with the effect")
    n_params: int = Field(description="fitted parameters, β/Vt, Kce and Kq included (and the valve's null where it is "
                                      "fitted: valve_null)")
    fit_nrmse: float = Field(description="NRMSE of the fit on all runs")
    heldout_nrmse_before: float = Field(description="held-out NRMSE of the re-fitted linear model ('none'), geometric mean over runs")
    heldout_nrmse_after: float = Field(description="held-out NRMSE with this effect, geometric mean over runs")
    shrink: float = Field(description="fraction of the held-out gap removed: 1 − after/before")
    score: float = Field(description="penalised geometric-mean held-out NRMSE²; lower is better")
    by_run: list[RunShrink]
    valve_null: Value | None = Field(None, description="the current [mA] at which the valve passes no flow, fitted with "
                                                       "this candidate (95 % interval), where the rests show a null "
                                                       "they disagree on (friction holding the rig around it); "
                                                       "null where no null is fitted")


#: What a verdict's explanation carries where the friction test broke a tie in Coulomb friction's favour
#: (:func:`grader.gap.evidence.coulomb_tie`; the summary looks for it).
TIE_TO_COULOMB = "so the tie goes to coulomb_friction"


class Verdict(_Frozen):
    effect: str
    margin: float = Field(description="ln(score of the runner-up / score of the verdict); 0 = a tie")
    runner_up: str | None
    confidence: float = Field(ge=0, le=1, description="share of run-bootstrap resamples with the same winner")
    indistinguishable_from: list[str] = Field(description="candidates the data cannot tell apart from the verdict")
    second_effect: str | None = None
    shares: dict[str, float] = Field(default_factory=dict, description=(
        "each named effect's share of the held-out shrink (sums to 1; where the replay named the second effect, of "
        "what the pair explains of the replayed runs' sum of squares)"))
    separating_test: str | None = Field(None, description="the extra test that would separate the verdict from a candidate the data cannot tell apart from it (for a 'none' verdict, or show an effect it cannot rule out)")
    explanation: str
    second_indistinguishable_from: list[str] = Field(
        default_factory=list, description="effects the data cannot tell apart from second_effect: each also explains "
                                          "clearly more on top of the verdict, and scores or fits as well")
    second_separating_test: str | None = Field(None, description="the extra test that would separate second_effect "
                                                                 "from the first of second_indistinguishable_from")
    not_ruled_out: list[str] = Field(
        default_factory=list, description="effects a 'none' verdict cannot rule out: below what these data can show "
                                          "(up to the size the explanation gives); separating_test names the test "
                                          "that would show them. Unlike indistinguishable_from, no lookalike of a "
                                          "named effect")
    not_named: list[str] = Field(
        default_factory=list, description="effects the evidence beside the runs shows that the verdict does not name: "
                                          "a third effect where effect and second_effect are taken (a verdict names "
                                          "two at most), or viscous friction from the loop gain's deficit beside an "
                                          "ADC that matters (the runs' fits lack the ADC, which biases their Kq); "
                                          "the explanation says why")


class QuantizationInfo(_Frozen):
    """What a quantising ADC does, when the readings show one."""

    adc_step: Value
    share_of_step: float = Field(description="ADC step as a fraction of the step command")
    share_of_readoff: float | None = Field(None, description="ADC step as a fraction of the smallest error read off "
                                                             "at rest, at the end of a step or ramp run whose command "
                                                             "moves less than 10 counts there (None: no run ends at "
                                                             "rest, or no error there clearly above 0)")
    bits: float = Field(description="estimated bits of a ±10 V ADC (from the step and Kpot)")
    limit_cycle: bool = Field(description="the step runs end in a limit cycle of a few counts")
    matters: bool = Field(description="named as an effect: at least 1 % of the step command or (not dithered) of an "
                                      "error read off at rest, or a limit cycle, and not a print precision")
    steady_state_error_band: Value = Field(description="± band round the set-point in which a P loop may settle")
    print_precision: bool = Field(False, description="a decimal step the reading noise dithers: the file's print "
                                                     "precision, not an ADC")
    dithered: bool = Field(False, description="the reading noise dithers the lattice (white-noise RMS at least "
                                              "half a step): an error averaged over a run's end resolves below it")


class LoopGainInfo(_Frozen):
    """The flow test's Kq against the runs' loop gain (computed when the dataset has no friction test)."""

    flow_test_Kq: Value = Field(description="Kq from the flow test")
    runs_Kq: Value = Field(description="Kq of the linear model re-fitted to the runs with candidate `candidate`")
    candidate: str = Field("none", description="the candidate whose fit gave runs_Kq: 'none', or the one effect the runs name")
    deficit: float = Field(description="1 − runs_Kq / flow_test_Kq")
    deficit_z: float = Field(description="ln(flow_test_Kq / runs_Kq) in standard errors of the estimates combined (each the standard error of a normal 95 % interval as wide as its t interval; with volts feedback, the calibration's Kpot's too)")
    viscous_B: Value = Field(description="viscous friction that gives the runs' closed loop at the flow test's Kq")
    names_viscous: bool = Field(description="the deficit names viscous friction (at least 2.5 standard errors, and a B inside its interval explains it)")
    viscous_B_larger_root: Value | None = Field(
        None, description="where a realistic rig with more viscous friction and less leakage gives the same closed loop "
                          "(the larger root of B's quadratic), its B; viscous_B's interval then reaches up to it (at most "
                          "1.5 lbf*s/in). None: no such rig")


class ReplayInfo(_Frozen):
    """Effects fitted again to the runs replayed through the controller output the rig recorded (datasets with a
    ``u`` column on every run)."""

    of: Literal["verdict", "second_effect", "dropped_second_effect", "verdict_with_second_effect"] = Field(
        description="what was replayed: the verdict, the candidates tied with it and the other effects that explain "
                    "clearly more than 'none' and score within a factor e of it; or the second effect, its lookalikes "
                    "and the other additions that pass the bar and score within a factor e of it (each on top of the "
                    "verdict); where no addition passes the bar, every addition fitted and, as 'none', the verdict "
                    "alone; or (dropped_second_effect) a second effect the closed loop's bar named and, as 'none', the "
                    "verdict alone, where the replay did not bear it out: it is then not named; or "
                    "(verdict_with_second_effect) the verdict and the lookalikes it kept beside the pair, each with "
                    "the second effect on top: a lookalike that fits 'evidence' worse than the verdict there is "
                    "dropped")
    excess: dict[str, float] = Field(description="each candidate's replayed fit: its sum of squares above the best "
                                                 "one's, in units of the best one's mean square per sample (2·ln of a "
                                                 "likelihood ratio on white noise; 0 = the best)")
    evidence: float = Field(description="the difference in excess that tells two candidates apart")
    mean_square: float = Field(description="the best replayed fit's mean square per sample, in units of the reading "
                                           "noise's")
    decides: bool = Field(description="the best replayed fit is good enough to decide (mean_square at most 1.5); "
                                      "candidates `evidence` or more apart in excess are then told apart")


class Diagnosis(_Frozen):
    schema_: str = Field(SCHEMA, alias="schema")
    dataset: str
    station: str
    inputs_sha256: str
    generated_by: dict[str, str]
    baseline: BaselineModel
    noise: NoiseFloor
    gap: Gap
    readoffs: list[ReadOff]
    candidates: list[Candidate]
    verdict: Verdict
    quantization: QuantizationInfo | None = None
    static_evidence: dict[str, dict[str, Value]] = Field(
        default_factory=dict, description="effect parameters the static tests measure (friction test: Fc and B)")
    loop_gain: LoopGainInfo | None = Field(None, description="the flow test's Kq against the runs' loop gain "
                                                             "(datasets without a friction test)")
    replay: list[ReplayInfo] = Field(default_factory=list, description="candidates compared on the replayed runs "
                                                                       "(empty where the verdict is 'none', no other "
                                                                       "effect competes with it, the friction test broke "
                                                                       "a tie, or a run has no finite u column)")
    valve_null: Value | None = Field(None, description="the current [mA] at which the valve passes no flow in the runs "
                                                       "(its null, in the flow test's sense) with its 95 % interval, "
                                                       "read where the runs rest; every model has it in every run. "
                                                       "Where a rest before a command shows a null the rests disagree "
                                                       "on (friction holding the rig around it), the null each "
                                                       "candidate fits, the augmented model's here (the verdict's "
                                                       "fit, or the pair's). null where the rests read none: within 3 "
                                                       "standard errors of 0, disagreeing with no rest before a "
                                                       "command 4 standard errors off 0, still settling, finer than "
                                                       "half the readings' lattice step, or with no P or PD run")
    notes: list[str]

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)


def diagnosis_json(d: Diagnosis) -> str:
    """Canonical JSON text (two-space indent, keys in schema order, trailing newline)."""
    return json.dumps(d.model_dump(mode="json", by_alias=True), indent=2, ensure_ascii=False) + "\n"


def json_schema() -> dict[str, object]:
    """The JSON Schema of ``diagnosis.json``."""
    return Diagnosis.model_json_schema(by_alias=True)
