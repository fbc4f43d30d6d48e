"""The reports of a regression check (:mod:`eval.regress`): Markdown and JUnit XML.

One row per scan per figure (recorded, now, tolerance, verdict) and what changed; JUnit
has one testcase per scan whose failure names the figure and its numbers.  Neither holds
a timing: the same scans and results give the same bytes.
"""

from __future__ import annotations

from typing import Any

from eval.regress import Figure, Verification, _yes


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return _yes(v)
    if isinstance(v, float):
        return f"{v:.3f}" if v == v else "-"
    return str(v)


def _tol_cell(f: Figure) -> str:
    if f.tolerance is None:
        return "-"
    if isinstance(f.tolerance, str):
        return f.tolerance
    unit = " m" if f.name == "moved" else ""
    return f"{f.tolerance:g}{unit}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def markdown_report(v: Verification, title: str = "unseen regress verify") -> str:
    """The Markdown report: summary, one row per scan per figure, what changed, problems."""
    tol = v.tolerances
    def off(x: Any, unit: str = "") -> str:
        return "off" if x is None else f"{x:g}{unit}"

    lines = [f"# {title}", "", f"{v.summary()}: **{'PASS' if v.ok else 'FAIL'}**", "",
             f"Tolerances: f1 {off(tol.f1)}, size {off(tol.size)}, moved {off(tol.move, ' m')}, "
             f"fixed {off(tol.fixed)}, stands {tol.stands}.", ""]
    lines += ["| scan | figure | recorded | now | tolerance | verdict |",
              "|---|---|---|---|---|---|"]
    for s in v.scans:
        if not s.figures:
            verdict = {"error": "**ERROR**", "skipped": "skipped", "pass": "pass"}[s.status]
            lines.append(f"| {_cell(s.name)} | - | - | - | - | {verdict}: {_cell(s.message)} |")
            continue
        for f in s.figures:
            name = f.name if not f.versus or f.name.endswith(")") else f"{f.name} ({f.versus})"
            verdict = {"drop": "**DROP**", "pass": "pass", "info": "info"}[f.verdict]
            lines.append(f"| {_cell(s.name)} | {name} | {_fmt(f.recorded)} | {_fmt(f.now)} | "
                         f"{_tol_cell(f)} | {verdict} |")
    problems = v.problems
    if problems:
        lines += ["", "## Problems", ""] + [f"- {_cell(p)}" for p in problems]
    changed = [s for s in v.scans if s.changes]
    lines += ["", "## Changes", ""]
    if not changed:
        lines.append("Nothing changed.")
    for s in changed:
        lines += [f"### {s.name}", ""] + [f"- {c}" for c in s.changes] + [""]
    if v.skipped_files:
        lines += ["", "Not scans (skipped): " + ", ".join(v.skipped_files)]
    return "\n".join(lines).rstrip("\n") + "\n"


def junit_xml(v: Verification, suite: str = "unseen regress") -> str:
    """JUnit XML: one ``testcase`` per scan (``failure`` per drop, ``error``, ``skipped``)."""
    import xml.etree.ElementTree as ET

    root = ET.Element("testsuites", name=suite)
    ts = ET.SubElement(root, "testsuite", name=suite, tests=str(len(v.scans)),
                       failures=str(v.count("drop")), errors=str(v.count("error")),
                       skipped=str(v.count("skipped")))
    for s in v.scans:
        case = ET.SubElement(ts, "testcase", classname=suite.replace(" ", "."), name=s.name)
        if s.status == "drop":
            el = ET.SubElement(case, "failure", message=s.message, type="regression")
            el.text = "\n".join(f.message for f in s.drops) + (
                "\n\nchanges:\n" + "\n".join(s.changes) if s.changes else "")
        elif s.status == "error":
            ET.SubElement(case, "error", message=s.message, type="error")
        elif s.status == "skipped":
            ET.SubElement(case, "skipped", message=s.message)
        if s.figures:
            out = ET.SubElement(case, "system-out")
            out.text = "\n".join(f"{f.name}: recorded {_fmt(f.recorded)}, now {_fmt(f.now)}, "
                                 f"tolerance {_tol_cell(f)}, {f.verdict}" for f in s.figures)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


__all__ = ["junit_xml", "markdown_report"]
