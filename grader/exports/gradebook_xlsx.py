"""``gradebook.xlsx`` for the instructor: one row per submission and one column per item, plus
a sheet of item statistics (mean score, statuses, the most common mistakes and their counts).
Every sheet's header row is frozen (with the first column where it names the row) and its
columns sized to their content."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from openpyxl import Workbook

from grader.exports.cells import literal_text, xlsx_text
from grader.exports.sheets import fit_columns, header_row
from grader.grading.results import STATUSES, SubmissionResult


def _grades_sheet(wb: Workbook, results: Sequence[SubmissionResult], items: list[str]) -> None:
    ws = wb.active
    ws.title = "grades"
    ws.append(["submission_id", "students", "SIS user ids", "sections", "valid", "score", "max_score", *items, "error"])
    for r in results:
        points = {i.item: i.points for i in r.items}
        ws.append([xlsx_text(v) for v in (
            r.submission_id, "; ".join(s.name for s in r.students), "; ".join(s.sis_user_id for s in r.students),
            "; ".join(sorted({s.section for s in r.students if s.section})), "yes" if r.valid else "NO",
            r.score, r.max_score, *(points.get(n) for n in items), r.error or "")])


def item_statistics(results: Sequence[SubmissionResult], items: list[str]) -> list[list[object]]:
    """Rows: item, max, mean points, mean %, count per status, the three most common mistakes."""
    rows: list[list[object]] = []
    for name in items:
        got = [i for r in results for i in r.items if i.item == name]
        if not got:
            continue
        top = max(i.max_points for i in got)
        mean = sum(i.points for i in got) / len(got)
        statuses = Counter(i.status for i in got)
        mistakes = Counter(i.mistake for i in got if i.mistake)
        common = sorted(mistakes.items(), key=lambda kv: (-kv[1], kv[0]))[:3]
        rows.append([name, top, round(mean, 3), round(100 * mean / top, 1) if top else None,
                     *(statuses.get(s, 0) for s in STATUSES), "; ".join(f"{m} ({n})" for m, n in common)])
    return rows


def gradebook(results: Sequence[SubmissionResult], items: list[str]) -> Workbook:
    """The workbook (save it with :func:`grader.exports.atomic.workbook_bytes`)."""
    results = sorted(results, key=lambda r: r.submission_id)
    wb = Workbook()
    _grades_sheet(wb, results, items)
    st = wb.create_sheet("item statistics")
    st.append(["item", "max points", "mean points", "mean %", *STATUSES, "most common mistakes (count)"])
    for row in item_statistics(results, items):
        st.append(row)
    mk = wb.create_sheet("mistakes")
    mk.append(["item", "mistake", "submissions"])
    counts = Counter((i.item, i.mistake) for r in results for i in r.items if i.mistake)
    order = {name: k for k, name in enumerate(items)}
    for (item, mistake), n in sorted(counts.items(), key=lambda kv: (order.get(kv[0][0], len(order)), -kv[1], kv[0][1])):
        mk.append([item, mistake, n])
    for ws in wb.worksheets:
        header_row(ws, freeze_column="B" if ws.title != "mistakes" else "A")
        fit_columns(ws)
    return literal_text(wb)
