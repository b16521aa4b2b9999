"""The canonical answer items of the hydraulic positioner lab (a public contract).

Each item has a kind (how it is read and checked), its default unit (``None`` for
expressions, designs and gains, whose unit follows the key's feedback convention) and
a one-line description used by the XLSX template and the docs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Kind = Literal["quantity", "expression", "poles", "design"]


@dataclass(frozen=True)
class ItemSpec:
    name: str
    kind: Kind
    unit: str | None
    description: str


ITEMS: dict[str, ItemSpec] = {s.name: s for s in (
    ItemSpec("closed_loop_tf", "expression", None, "closed-loop transfer function X/R with P control, in the course's symbols"),
    ItemSpec("open_loop_tf", "expression", None, "open-loop transfer function L(s) with P control, in the course's symbols"),
    ItemSpec("char_poly", "expression", None, "characteristic polynomial in s (any s-free multiple; '= 0' allowed)"),
    ItemSpec("Kpot", "quantity", "V/in", "potentiometer gain"),
    ItemSpec("Kq", "quantity", "in**3/s/mA", "no-load valve flow gain (leakage subtracted)"),
    ItemSpec("leakage", "quantity", "in**3/s", "valve internal leakage flow"),
    ItemSpec("B", "quantity", "lbf*s/in", "viscous damping coefficient used in the model"),
    ItemSpec("Fc", "quantity", "lbf", "Coulomb friction force"),
    ItemSpec("omega_crit", "quantity", "rad/s", "oscillation frequency at the limit of stability"),
    ItemSpec("Kp_crit", "quantity", None, "proportional gain at the limit of stability"),
    ItemSpec("beta_over_Vt", "quantity", "psi/in**3", "bulk modulus over trapped volume, by coefficient matching (ζ = 0)"),
    ItemSpec("Kce", "quantity", "in**3/s/psi", "total flow-pressure coefficient, by coefficient matching (ζ = 0)"),
    ItemSpec("Kp_no_overshoot", "quantity", None, "predicted highest P gain without overshoot"),
    ItemSpec("Kp_25_overshoot", "quantity", None, "predicted P gain giving 25 % overshoot"),
    ItemSpec("ramp_ess_P", "quantity", "in", "predicted steady-state error of the P ramp run"),
    ItemSpec("closed_loop_poles", "poles", "1/s", "closed-loop poles at each gain of the lab's runs"),
    ItemSpec("pd_design", "design", None, "PD design: Kp, Kd and the step overshoot it gives"),
    ItemSpec("pi_design", "design", None, "PI design: Kp, Ki and the ramp error it leaves"),
)}

#: predictions a rig may not have (e.g. no gain gives 25 % overshoot): they may be answered
#: "not reachable" (see :mod:`grader.grading.unreachable`)
MAY_BE_NOT_REACHABLE = frozenset({"Kp_no_overshoot", "Kp_25_overshoot", "ramp_ess_P"})
#: values read off the instability run: "not identifiable" when it shows no critical oscillation
MAY_BE_NOT_IDENTIFIABLE = frozenset({"omega_crit", "Kp_crit", "beta_over_Vt", "Kce"})
