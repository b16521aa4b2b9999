"""The identification students perform, estimator-style (``fit`` returns ``self``;
learned results end in ``_`` and are :class:`Estimate` objects with units and 95 % intervals)."""

from grader.identify.critical import coefficient_match, match_sampled_poles
from grader.identify.estimate import Estimate, not_identifiable, propagate
from grader.identify.flow import FlowGainFit
from grader.identify.friction import FrictionFit
from grader.identify.oscillation import OscillationFit
from grader.identify.pipeline import Identification, command_start, identify
from grader.identify.pot import PotCalibration
from grader.identify.predict import predictions

__all__ = [
    "Estimate", "FlowGainFit", "FrictionFit", "Identification", "OscillationFit", "PotCalibration",
    "coefficient_match", "command_start", "identify", "match_sampled_poles", "not_identifiable",
    "predictions", "propagate",
]
