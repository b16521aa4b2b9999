"""The paper's run plan: gains are in the volts convention, converted once to the rig's own."""
from __future__ import annotations

import pytest

from grader.model import zloop
from grader.stations import Station
from grader.synth import paper_runs


@pytest.mark.parametrize("feedback", ["volts", "inches"])
def test_instability_run_is_just_above_critical_in_either_convention(station: Station, feedback: str) -> None:
    p = station.model_copy(update={"feedback": feedback}).params()
    runs = {r.name: r for r in paper_runs(p)}
    k_crit = zloop.critical_gain(p)  # native convention
    k_run = runs["instability"].controller.Kp
    assert k_crit < k_run <= k_crit * 1.015 + 0.5 * p.Kpot / p.k_fb + 1e-9
    assert not zloop.is_stable(p, runs["instability"].controller)
    # same loop gain in both conventions: Kp * k_fb does not depend on the convention
    assert runs["step_kp46"].controller.Kp * p.k_fb == pytest.approx(46 * p.Kpot)
