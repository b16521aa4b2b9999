"""Effect names, parameter parsing with units, range checks and round trips."""

from __future__ import annotations

import pickle

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.errors import SimulationError
from grader.model.effects import EFFECT_NAMES, EFFECTS, EffectSet

CANONICAL = {
    "coulomb_friction": ["Fc"], "viscous_friction": ["B"], "valve_saturation": ["i_max"],
    "valve_deadband": ["width"], "valve_hysteresis": ["width"], "pressure_flow_nonlinearity": [],
    "sampling_delay": ["delay"], "valve_dynamics": ["tau", "order", "zeta"],
    "sensor_quantization": ["bits"], "sensor_noise": ["sigma"],
}


def test_canonical_names_and_parameters_are_the_public_contract() -> None:
    assert set(EFFECT_NAMES) == set(CANONICAL)
    for name, params in CANONICAL.items():
        assert [p.name for p in EFFECTS[name].params] == params


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_defaults_and_typical_ranges_lie_inside_the_admissible_range(name: str) -> None:
    for p in EFFECTS[name].params:
        assert p.lo <= p.typical[0] <= p.typical[1] <= p.hi
        assert p.lo <= p.default <= p.hi
    assert EFFECTS[name].rationale


@pytest.mark.parametrize(
    ("text", "effect", "param", "value"),
    [
        ("coulomb_friction:Fc=4lbf", "coulomb_friction", "Fc", 4.0),
        ("coulomb_friction:Fc=17.79 N", "coulomb_friction", "Fc", 17.79 / 4.4482216152605),
        ("sampling_delay:delay=2ms", "sampling_delay", "delay", 0.002),
        ("valve_saturation:i_max=0.03 A", "valve_saturation", "i_max", 30.0),
        ("viscous_friction:B=0.2 lbf*s/in", "viscous_friction", "B", 0.2),
        ("sensor_noise:sigma=0.4 thou", "sensor_noise", "sigma", 0.0004),
        ("sensor_noise:sigma=0.01 mm", "sensor_noise", "sigma", 0.01 / 25.4),
        ("sensor_quantization:bits=12", "sensor_quantization", "bits", 12.0),
        ("sensor_quantization:bits=12 bit", "sensor_quantization", "bits", 12.0),
        ("valve_dynamics:tau=2ms,order=2", "valve_dynamics", "order", 2.0),
        ("valve_dynamics", "valve_dynamics", "tau", EFFECTS["valve_dynamics"].param("tau").default),
        ("sampling_delay:delay=0", "sampling_delay", "delay", 0.0),  # zero needs no unit
    ],
)
def test_parse_converts_quantities_to_internal_units(text: str, effect: str, param: str, value: float) -> None:
    assert EffectSet.parse([text]).value(effect, param) == pytest.approx(value, rel=1e-9)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("coulomb:Fc=1lbf", "did you mean coulomb_friction"),
        ("coulomb_friction:F=1lbf", "has no parameter 'F'"),
        ("coulomb_friction:Fc=4", "needs a unit"),
        ("coulomb_friction:Fc=4 s", "is not a force"),
        ("coulomb_friction:Fc=4 furlongs", "is not a force"),
        ("coulomb_friction:Fc=-1lbf", "out of range"),
        ("coulomb_friction:Fc=1e6 lbf", "out of range"),
        ("sampling_delay:delay=1 s", "out of range"),
        ("sensor_quantization:bits=12.5", "whole number"),
        ("valve_dynamics:order=3", "out of range"),
        ("pressure_flow_nonlinearity:Ps=1000psi", "no parameter"),
        ("sensor_noise:sigma=0.4 mil", "'mil' as an angle"),
        ("coulomb_friction:Fc", "not 'param=quantity'"),
        ("coulomb_friction:Fc=1lbf,Fc=2lbf", "given twice"),
        ("9lives", "expected 'name'"),
    ],
)
def test_parse_rejects_with_a_clear_message(text: str, message: str) -> None:
    with pytest.raises(SimulationError, match=message):
        EffectSet.parse([text])


def test_repeated_effect_merges_parameters_but_not_the_same_one_twice() -> None:
    e = EffectSet.parse(["valve_dynamics:tau=2ms", "valve_dynamics:order=2"])
    assert (e.value("valve_dynamics", "tau"), e.value("valve_dynamics", "order")) == (0.002, 2.0)
    with pytest.raises(SimulationError, match="given twice"):
        EffectSet.parse(["valve_dynamics:tau=2ms", "valve_dynamics:tau=3ms"])


def test_an_effect_set_survives_pickling_for_worker_processes() -> None:
    e = EffectSet.parse(["valve_dynamics:tau=2ms,order=2", "coulomb_friction:Fc=3lbf"])
    back = pickle.loads(pickle.dumps(e))
    assert back == e and hash(back) == hash(e) and back.names == e.names
    with pytest.raises(TypeError):  # still read-only after the trip
        back.values["coulomb_friction"]["Fc"] = 1.0  # type: ignore[index]


def test_constructor_checks_names_parameters_and_ranges() -> None:
    with pytest.raises(SimulationError, match="unknown effect"):
        EffectSet({"backlash": {}})
    with pytest.raises(SimulationError, match="out of range"):
        EffectSet({"coulomb_friction": {"Fc": -2.0}})
    assert EffectSet({"coulomb_friction": {}}).value("coulomb_friction", "Fc") == EFFECTS["coulomb_friction"].params[0].default


def test_merged_takes_an_effect_whole_from_the_other_set_and_without_drops() -> None:
    base = EffectSet.parse(["coulomb_friction:Fc=1lbf", "valve_dynamics:tau=3ms,order=2"])
    out = base.merged(EffectSet.parse(["valve_dynamics:tau=1ms", "sampling_delay:delay=1ms"]))
    assert out.value("coulomb_friction", "Fc") == 1.0
    assert (out.value("valve_dynamics", "tau"), out.value("valve_dynamics", "order")) == (0.001, 1.0)
    assert out.without("coulomb_friction").names == ("sampling_delay", "valve_dynamics")
    assert not EffectSet() and "sampling_delay" in out


_values = st.fixed_dictionaries({
    name: st.fixed_dictionaries({
        p.name: (st.integers(int(p.lo), int(p.hi)).map(float) if p.integer
                 else st.floats(p.lo, p.hi, allow_nan=False, allow_infinity=False))
        for p in spec.params
    })
    for name, spec in EFFECTS.items()
})


@settings(max_examples=60, deadline=None)
@given(values=_values, keep=st.sets(st.sampled_from(EFFECT_NAMES)))
def test_quantity_strings_round_trip_exactly_enough(values: dict, keep: set) -> None:
    e = EffectSet({n: v for n, v in values.items() if n in keep})
    back = EffectSet.from_quantities(e.to_quantities())
    assert back.names == e.names
    for name in e.names:
        for p, v in e.values[name].items():
            assert back.value(name, p) == pytest.approx(v, rel=1e-11, abs=1e-300)
