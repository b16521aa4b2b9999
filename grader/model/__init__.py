"""The physics: pure functions and frozen dataclasses, no I/O.

Reading order: :mod:`params` (RigParams, Controller), :mod:`symbolic` (sympy block-diagram
reduction), :mod:`linear` (python-control TFs, Routh critical gain, root locus),
:mod:`sampled` (the digital loop with ZOH), :mod:`effects` (canonical unmodelled effects)
and :mod:`rig` (the nonlinear rig simulator).
"""

from grader.model.effects import EffectSet
from grader.model.linear import (
    char_poly,
    closed_loop_poles,
    closed_loop_tf,
    critical_gain,
    open_loop_tf,
    plant_tf,
    ramp_error,
    root_locus,
)
from grader.model.params import Controller, RigParams, mass_from_weight, piston_area
from grader.model.rig import simulate_rig, simulate_rig_batch
from grader.model.sampled import discrete_critical_gain, simulate

__all__ = [
    "Controller", "EffectSet", "RigParams", "char_poly", "closed_loop_poles", "closed_loop_tf", "critical_gain",
    "discrete_critical_gain", "mass_from_weight", "open_loop_tf", "piston_area", "plant_tf", "ramp_error",
    "root_locus", "simulate", "simulate_rig", "simulate_rig_batch",
]
