"""The self-check page: one labelled input per rubric item, grouped as the lab handout groups them.

The page holds item names, descriptions and unit hints only (never a key value); it is
rendered once per worker from ``templates/index.html``.
"""

from __future__ import annotations

import html
from pathlib import Path
from string import Template

from grader.grading.items import ITEMS
from grader.grading.rubric import Rubric
from grader.model.symbolic import COURSE_SYMBOLS

TEMPLATE = Path(__file__).parent / "templates" / "index.html"

#: The handout's order: prelab, week-1 characterisation, identification, predictions, designs.
GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Prelab: transfer functions", ("closed_loop_tf", "open_loop_tf", "char_poly")),
    ("Characterisation", ("Kpot", "Kq", "leakage", "B", "Fc")),
    ("Identification", ("omega_crit", "Kp_crit", "beta_over_Vt", "Kce")),
    ("Predictions", ("Kp_no_overshoot", "Kp_25_overshoot", "ramp_ess_P", "closed_loop_poles")),
    ("Designs", ("pd_design", "pi_design")),
)
_HINTS = {
    "expression": "symbols " + ", ".join(n for n in COURSE_SYMBOLS) + "; products with * or a space",
    "poles": "one gain a line, e.g. Kp=10: -20+150j, -20-150j, -12 (add Ki=… or Kd=… if used)",
    "pd_design": "Kp = …, Kd = … s, overshoot = … %",
    "pi_design": "Kp = …, Ki = … 1/s, ramp_error = … in",
}


def _hint(name: str, rubric: Rubric) -> str:
    spec = ITEMS[name]
    if spec.kind == "quantity":
        unit = rubric.items[name].unit or spec.unit
        return f"unit: {unit.replace('**', '^')}" if unit else "a gain (dimensionless in the volts convention)"
    return _HINTS.get(name) or _HINTS[spec.kind]


def _field(name: str, rubric: Rubric) -> str:
    spec, e = ITEMS[name], html.escape
    box = ("<textarea id='a-{n}' name='{n}' rows='3' data-testid='answer-{n}' data-kind='{k}' "
           "aria-describedby='h-{n} r-{n}' spellcheck='false'></textarea>" if spec.kind == "poles" else
           "<input id='a-{n}' name='{n}' type='text' data-testid='answer-{n}' data-kind='{k}' "
           "aria-describedby='h-{n} r-{n}' autocomplete='off' spellcheck='false'>")
    preview = (f"<div class='preview' id='p-{e(name)}' aria-live='polite'></div>"
               if spec.kind in ("expression", "quantity") else "")
    return (f"<div class='item'><label for='a-{e(name)}'><code>{e(name)}</code> {e(spec.description)}</label>"
            + box.format(n=e(name), k=e(spec.kind))
            + f"<small id='h-{e(name)}' class='hint'>{e(_hint(name, rubric))}</small>{preview}"
            f"<div class='result' id='r-{e(name)}' data-testid='result-{e(name)}'></div></div>")


def _groups(rubric: Rubric) -> list[tuple[str, list[str]]]:
    listed = {n for _, names in GROUPS for n in names}
    out = [(title, [n for n in names if n in rubric.items]) for title, names in GROUPS]
    other = [n for n in rubric.items if n not in listed and n in ITEMS]
    return [g for g in (*out, ("Other items", other)) if g[1]]


def render_page(rubric: Rubric, stations: list[str]) -> str:
    """The whole HTML page for ``rubric``'s items and the installed ``stations``."""
    e = html.escape
    options = "".join(f"<option value='{e(s)}'>{e(s)}</option>" for s in stations) or \
        "<option value='default'>default (prelab only: no lab data installed)</option>"
    sections = "".join(
        f"<fieldset><legend>{e(title)}</legend>{''.join(_field(n, rubric) for n in names)}</fieldset>"
        for title, names in _groups(rubric))
    return Template(TEMPLATE.read_text(encoding="utf-8")).substitute(
        title=e(rubric.title or "Lab self-check"), stations=options, sections=sections)
