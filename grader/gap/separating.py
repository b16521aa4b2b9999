"""The extra test that would separate two effects the data cannot tell apart."""

from __future__ import annotations

from collections.abc import Sequence

#: Unordered pair of effects (or an effect and ``none``) -> the test that separates them.
TESTS: dict[frozenset[str], str] = {
    frozenset({"coulomb_friction", "valve_deadband"}):
        "a slow ramp in both directions with the valve current recorded: deadband stops the flow below a current "
        "threshold, friction holds the load until the pressure force exceeds Fc",
    frozenset({"coulomb_friction", "valve_hysteresis"}):
        "a slow triangle wave: backlash delays each reversal by half its width in current, friction makes the "
        "load stick at each reversal",
    frozenset({"valve_deadband", "valve_hysteresis"}):
        "a flow test sweeping the current up and then down: hysteresis gives two branches, deadband one flat zone",
    frozenset({"sampling_delay", "valve_dynamics"}):
        "a step recorded at a faster sample rate (a delay shifts the first milliseconds, a spool lag rounds them) "
        "or the oscillation frequency at two gains near the critical gain (a delay costs phase only, a lag also gain)",
    frozenset({"valve_saturation", "pressure_flow_nonlinearity"}):
        "steps of several sizes: a current limit caps the speed, the orifice law slows it with the load pressure",
    frozenset({"viscous_friction", "none"}):
        "the friction test at several speeds: viscous friction is the slope of force against speed",
}
GENERIC = "steps of several sizes and a slow ramp in both directions"


def separating_test(effect: str, others: Sequence[str]) -> str | None:
    """The test that would separate ``effect`` from the first of ``others`` (None if there are none)."""
    if not others:
        return None
    return TESTS.get(frozenset({effect, others[0]}), GENERIC)


def would(test: str | None, does: str) -> str:
    """"<test> would <does> (<why>)" from a separating test "<test>: <why>" (None: another test)."""
    head, _, why = (test or "another test").partition(": ")
    return f"{head} would {does}" + (f" ({why})" if why else "")
