"""Self-contained HTML reports: inline CSS, charts embedded as base64 PNG, no scripts."""

from __future__ import annotations

import base64
import html
from collections.abc import Iterable, Mapping

from grader.assess.claims import format_p
from grader.assess.exam_report import informative_heading
from grader.assess.mapping import FORM_NAMES
from grader.assess.schemas import ExamReport, SurveyReport
from grader.assess.views import (
    Value,
    View,
    exam_views,
    survey_comparisons,
    survey_hours,
    survey_most_useful,
    survey_summary,
)

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:2rem auto;max-width:72rem;
padding:0 1rem;color:#222;line-height:1.45}
h1{font-size:1.6rem}h2{font-size:1.25rem;margin-top:2rem;border-bottom:1px solid #ddd}
h3{font-size:1rem;margin-bottom:.3rem}
table{border-collapse:collapse;font-size:.85rem;margin:.5rem 0 1rem}
th,td{border:1px solid #ddd;padding:.25rem .5rem;vertical-align:top}
th{background:#f3f3f3;text-align:left}td.n{text-align:right;font-variant-numeric:tabular-nums}
img{max-width:100%;height:auto}.supported{color:#0a5d00}.unsupported{color:#8a3b00}
.meta{color:#555}blockquote{margin:.3rem 0 .3rem 1rem;color:#333}
"""


def fmt(value: Value, kind: str) -> str:
    """A table value as text; missing values are a dash."""
    if value is None:
        return "–"
    if kind == "text":
        return str(value)
    if kind == "int" or (kind == "num" and isinstance(value, int)):
        return str(int(value))
    v = float(value)
    if kind == "pct":
        return f"{v:.1f}"
    if kind == "p":
        return format_p(v)
    return f"{v:.2f}"


def _esc(text: object) -> str:
    return html.escape(str(text), quote=True)


def _cell(value: Value, kind: str) -> str:
    css = "" if kind == "text" else ' class="n"'
    return f"<td{css}>{_esc(fmt(value, kind))}</td>"


def table(view: View) -> str:
    head = "".join(f"<th>{_esc(h)}</th>" for h in view.headers)
    body = "".join(
        "<tr>" + "".join(_cell(v, k) for v, k in zip(row, view.kinds, strict=True)) + "</tr>" for row in view.rows
    )
    return f"<h3>{_esc(view.title)}</h3><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def image(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<p><img alt="{_esc(alt)}" src="data:image/png;base64,{data}"></p>'


def _values(values: list[int]) -> str:
    return "none" if not values else (f"{values[0]}" if len(values) == 1 else f"{values[0]}-{values[-1]}")


def _list(items: Iterable[str]) -> str:
    return "<ul>" + "".join(f"<li>{_esc(i)}</li>" for i in items) + "</ul>"


def page(title: str, sections: Iterable[str]) -> str:
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{_esc(title)}</title>'
        f"<style>{_CSS}</style></head><body><h1>{_esc(title)}</h1>\n" + "\n".join(sections) + "\n</body></html>\n"
    )


def survey_html(report: SurveyReport, images: Mapping[str, bytes]) -> str:
    """The survey report page."""
    claims = "".join(
        f'<p class="{"supported" if c.supported else "unsupported"}">{_esc(c.conclusion)}</p>'
        for c in report.comparisons
    )
    sections = [
        f'<p class="meta">{report.respondents} respondents, read from a {FORM_NAMES[report.form]}. '
        f"Scale: {_esc('; '.join(f'{i} = {label}' for i, label in enumerate(report.scale.labels, 1)))}. "
        f"Disagree = {_values(report.scale.disagree)}, neutral = {_values(report.scale.neutral)}, agree = "
        f"{_values(report.scale.agree)}; missing answers are left out, never counted as neutral.</p>",
        "<h2>Which lab was rated highest?</h2>" + claims,
        "<h2>Ratings</h2>" + image(images["likert"], "Diverging stacked bar chart of the ratings"),
        "".join(table(v) for v in survey_summary(report)),
        "<h2>Comparisons across labs</h2>" + "".join(table(v) for v in survey_comparisons(report)),
    ]
    if report.hours is not None:
        chart = image(images["hours"], "Hours per week") if "hours" in images else ""
        sections.append("<h2>Hours per week outside lab</h2>" + chart + "".join(table(v) for v in survey_hours(report)))
    if report.most_useful is not None:
        sections.append("<h2>Most useful lab, and why</h2>" + "".join(table(v) for v in survey_most_useful(report)))
    sections.append("<h2>What these data can and cannot show</h2>" + _list(report.limitations))
    if report.notes:
        sections.append("<h2>Data notes</h2>" + _list(report.notes))
    return page("Laboratory survey report", sections)


def exam_html(report: ExamReport, images: Mapping[str, bytes]) -> str:
    """The embedded exam-question report page."""
    verdicts = "".join(f"<p>{_esc(p.verdict)}</p>" for p in report.problems)
    sections = [
        f'<p class="meta">{report.students} students; scores are the {report.unit}. Groups: '
        f"{report.treated} vs {report.control}.</p>",
        "<h2>What the comparison shows</h2>" + verdicts,
        f"<h2>{_esc(informative_heading(report))}</h2>" + _list(report.why_uninformative),
        "<h2>How big the next study has to be</h2>" + _list(report.next_study),
        "<h2>Score distributions</h2>" + image(images["exam"], "Item scores by group"),
        "<h2>Figures</h2>" + "".join(table(v) for v in exam_views(report)),
        "<h2>Notes</h2>" + _list(report.notes),
    ]
    return page("Embedded exam question report", sections)
