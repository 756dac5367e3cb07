"""A report's two documents from its sections: ``index.html`` and ``README.md``, rendered by the Jinja2 templates
of ``workbench/reporting/report/templates`` (autoescaped HTML; Markdown as written), with the page's style sheet and
scripts read from ``workbench/reporting/report/static`` and inlined, so that the page needs nothing beside its folder.

A section's blocks are paragraphs (Markdown's `code` and **bold** become tags in the HTML), bullet lists, tables
(pandas DataFrames), figures (:class:`~workbench.reporting.report.run_figures.FigureEntry`) and the faces you can turn
(:class:`~workbench.reporting.report.faces.FacesBlock`).
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Sequence

import pandas as pd

from workbench.core.files import inside, write_atomic
from workbench.reporting.report.faces import FacesBlock
from workbench.reporting.report.run_figures import FigureEntry
from workbench.reporting.report.sections import Section
from workbench.reporting.tables.cells import frame_cells, markdown_frame

STRONG = re.compile(r"\*\*([^*]+)\*\*")
CODE = re.compile(r"`([^`]+)`")
SHORT_CELL = 24
"""Table cells up to this many characters stay on one line; longer text wraps (class ``txt``)."""


def inline_spans(text: str) -> list[tuple[bool, bool, str]]:
    """A paragraph's Markdown ``**bold**`` and `` `code` `` as spans for the HTML template.

    Returns
    -------
    list of (bool, bool, str)
        (bold, code, text) of each span, in order.
    """
    spans = []
    for bold, piece in _split(STRONG, text):
        spans += [(bold, code, part) for code, part in _split(CODE, piece)]
    return spans


def _split(pattern: re.Pattern, text: str) -> list[tuple[bool, str]]:
    """``text`` cut at the matches of ``pattern``: (matched, text) pieces, a match by its group 1."""
    pieces, at = [], 0
    for match in pattern.finditer(text):
        pieces += [(False, text[at : match.start()]), (True, match[1])]
        at = match.end()
    return [(matched, piece) for matched, piece in [*pieces, (False, text[at:])] if piece]


@lru_cache(maxsize=None)
def environment():
    """The templates' Jinja2 environment: HTML autoescaped, Markdown not; blocks trimmed so that a template's
    layout is the document's."""
    from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape

    env = Environment(
        loader=PackageLoader("workbench.reporting.report", "templates"),
        autoescape=select_autoescape(enabled_extensions=("html",), default_for_string=True, default=False),
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
        undefined=StrictUndefined,
    )
    env.filters["spans"] = inline_spans
    return env


def static_text(name: str):
    """A file of ``workbench/reporting/report/static`` (the package's own style sheets and scripts), marked safe to
    inline."""
    from markupsafe import Markup

    return Markup(resources.files("workbench.reporting.report").joinpath("static", name).read_text(encoding="utf-8"))


def _table_block(frame: pd.DataFrame, markdown: bool) -> dict:
    if markdown:
        return {"kind": "table", "text": markdown_frame(frame)}
    header, rows, numeric = frame_cells(frame)
    cells = [
        [
            (text, "num" if is_number else ("" if len(text) <= SHORT_CELL else "txt"))
            for text, is_number in zip(row, numeric)
        ]
        for row in rows
    ]
    return {"kind": "table", "header": list(header), "rows": cells}


def _block(block, markdown: bool) -> dict:
    if isinstance(block, FigureEntry):
        files = [{"path": name, "format": name.rsplit(".", 1)[1].upper()} for name in block.files]
        return {
            "kind": "figure",
            "stem": block.stem,
            "title": block.title,
            "caption": block.caption,
            "missing": block.missing,
            "files": files,
        }
    if isinstance(block, FacesBlock):
        return {
            "kind": "faces",
            "view": block.view,
            "view_caption": block.view_caption,
            "animation": block.animation,
            "caption": block.caption,
            "missing": block.missing,
        }
    if hasattr(block, "page_block"):  # a block that says how the templates show it (the rig panel)
        return block.page_block(markdown)
    if isinstance(block, pd.DataFrame):
        return _table_block(block, markdown)
    if isinstance(block, list):
        return {"kind": "list", "items": [str(item) for item in block]}
    return {"kind": "text", "text": str(block)}


def page_sections(sections: Sequence[Section], markdown: bool) -> list[dict]:
    """The sections as the templates read them: a heading and blocks, each a dict with its ``kind``."""
    return [
        {"heading": section.heading, "blocks": [_block(block, markdown) for block in section.blocks]}
        for section in sections
    ]


def render_markdown(title: str, sections: Sequence[Section]) -> str:
    """README.md of a report."""
    text = environment().get_template("report.md").render(title=title, sections=page_sections(sections, True))
    return text.rstrip() + "\n"


def render_html(title: str, sections: Sequence[Section]) -> str:
    """index.html of a report: one self-contained page, figures beside it in ``figures/``."""
    return (
        environment()
        .get_template("report.html")
        .render(
            title=title,
            sections=page_sections(sections, False),
            style=static_text("report.css"),
            figure_check=static_text("figure_check.js"),
            view_style=static_text("view3d.css"),
            view_script=static_text("view3d.js"),
            rig_style=static_text("rig_panel.css"),
            rig_script=static_text("rig_panel.js"),
        )
    )


def write_documents(out: Path, title: str, sections: Sequence[Section]) -> None:
    """Write ``index.html`` and ``README.md`` of a report into ``out``."""
    write_atomic(inside(out, "index.html"), render_html(title, sections))
    write_atomic(inside(out, "README.md"), render_markdown(title, sections))
