"""Deterministic file contents: fixed zip and workbook timestamps (atomic writing: :mod:`grader.outpaths`)."""

from __future__ import annotations

import io
import re
import zipfile
from collections.abc import Iterable
from datetime import datetime

from openpyxl import Workbook

ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
WORKBOOK_TIME = datetime(2000, 1, 1)


def zip_bytes(entries: Iterable[tuple[str, bytes, int]]) -> bytes:
    """A zip of ``(name, data, unix mode)`` entries with fixed timestamps, in the given order."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data, mode in entries:
            info = zipfile.ZipInfo(name, date_time=ZIP_EPOCH)
            info.external_attr = (0o100000 | mode) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, data)
    return buf.getvalue()


def workbook_bytes(wb: Workbook) -> bytes:
    """An openpyxl workbook as deterministic XLSX bytes (fixed document times and zip timestamps)."""
    wb.properties.created = WORKBOOK_TIME
    wb.properties.modified = WORKBOOK_TIME
    wb.properties.creator = "grader"
    wb.properties.lastModifiedBy = "grader"
    raw = io.BytesIO()
    wb.save(raw)  # openpyxl stamps the save time as dcterms:modified; pin it
    stamp = WORKBOOK_TIME.strftime("%Y-%m-%dT%H:%M:%SZ").encode()

    def part(name: str, data: bytes) -> bytes:
        return re.sub(rb"(<dcterms:modified[^>]*>)[^<]*", rb"\g<1>" + stamp, data) if name == "docProps/core.xml" else data

    with zipfile.ZipFile(io.BytesIO(raw.getvalue())) as z:
        return zip_bytes((i.filename, part(i.filename, z.read(i)), 0o644) for i in z.infolist())
