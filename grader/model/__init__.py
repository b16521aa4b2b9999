"""The physics: pure functions and frozen dataclasses, no I/O.

Reading order: :mod:`params` (RigParams, Controller), :mod:`symbolic` (sympy block-diagram
reduction), :mod:`linear` (python-control TFs, Routh critical gain, root locus),
:mod:`sampled` (the digital loop with ZOH), :mod:`effects` (canonical unmodelled effects)
and :mod:`rig` (the nonlinear rig simulator).
"""

from importlib import import_module
from typing import Any

#: Public name -> defining module, imported on first use (so ``grader.model.params`` stays light).
_EXPORTS = {
    "EffectSet": "effects", "char_poly": "linear", "closed_loop_poles": "linear", "closed_loop_tf": "linear",
    "critical_gain": "linear", "open_loop_tf": "linear", "plant_tf": "linear", "ramp_error": "linear",
    "root_locus": "linear", "Controller": "params", "RigParams": "params", "mass_from_weight": "params",
    "piston_area": "params", "simulate_rig": "rig", "simulate_rig_batch": "rig",
    "discrete_critical_gain": "sampled", "simulate": "sampled",
}


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)


__all__ = [
    "Controller", "EffectSet", "RigParams", "char_poly", "closed_loop_poles", "closed_loop_tf", "critical_gain",
    "discrete_critical_gain", "mass_from_weight", "open_loop_tf", "piston_area", "plant_tf", "ramp_error",
    "root_locus", "simulate", "simulate_rig", "simulate_rig_batch",
]
