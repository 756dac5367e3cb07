"""The one table writer: cell texts, and the same table as Markdown, LaTeX or HTML.

A table is a header, rows of cell texts and which columns hold numbers (right-aligned). The alpha table a run
prints, the tables of ``workbench collect`` and those of ``workbench report`` are all written here.
"""

from __future__ import annotations

import html
import math
from typing import Sequence

import numpy as np
import pandas as pd

FLOAT_FORMATS = {
    "coverage": "{:.4f}",
    "alpha_abs_mean": "{:.3f}",
    "alpha_abs_pooled": "{:.3f}",
    "alpha_disp_mean": "{:.2f}",
    "alpha_disp_pooled": "{:.2f}",
    "rms_mm": "{:.3f}",
    "paper_alpha": "{:.2f}",
    "err_mm_median": "{:.3f}",
    "err_mm_p95": "{:.3f}",
    "err_mm_max": "{:.3f}",
    "w_max_abs": "{:.3g}",
    "w_outside_01": "{:.2f}",
    "w_sparsity": "{:.2f}",
    "w_roughness": "{:.3g}",
}
"""Decimals of the alpha table's columns, wherever they are shown."""
THREE_DECIMALS = ("relative", "cosine", "relative_distance", "matched_abs_cosine", "locality", "usage")
"""Other columns shown with three decimals (intuitiveness measures)."""


def is_missing(value) -> bool:
    """None, pandas' NA and NaN."""
    return value is None or value is pd.NA or (isinstance(value, (float, np.floating)) and math.isnan(value))


def cell_text(column: str, value) -> str:
    """Text of one table cell.

    The alpha table's decimals per column (also for ``<column>_ci_low``, ``<column>_ci_high`` and
    ``<column> <solver>``), ``-`` for a missing number, three decimals for intuitiveness measures and four
    significant digits for other floats.
    """
    if is_missing(value):
        return "-"
    if isinstance(value, (float, np.floating)):
        base = column.split(" ")[0].removesuffix("_ci_low").removesuffix("_ci_high").removeprefix("clean_")
        if base in FLOAT_FORMATS:
            return FLOAT_FORMATS[base].format(value)
        if base in THREE_DECIMALS:
            return f"{value:.3f}"
        return f"{value:.4g}"
    return str(value)


def frame_cells(frame: pd.DataFrame) -> tuple[list[str], list[list[str]], list[bool]]:
    """Header, cell texts and which columns are numeric (right-aligned) of a DataFrame."""
    columns = [str(column) for column in frame.columns]
    numeric = [
        pd.api.types.is_numeric_dtype(frame[column]) and not pd.api.types.is_bool_dtype(frame[column])
        for column in frame.columns
    ]
    rows = [
        [cell_text(column, value) for column, value in zip(columns, values)] for values in frame.itertuples(index=False)
    ]
    return columns, rows, numeric


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]], numeric: Sequence[bool]) -> str:
    """GitHub-flavoured Markdown, numeric columns right-aligned, columns padded to one width.

    Returns
    -------
    str
        Lines joined by newlines, with a trailing newline.
    """
    rows = [[text.replace("|", "\\|") for text in row] for row in rows]  # a pipe would end the cell
    widths = [max([len(name)] + [len(row[i]) for row in rows]) for i, name in enumerate(header)]

    def line(values):
        return (
            "| "
            + " | ".join(
                value.rjust(width) if is_number else value.ljust(width)
                for value, width, is_number in zip(values, widths, numeric)
            )
            + " |"
        )

    rule = (
        "|"
        + "|".join(
            ("-" * (width + 1) + ":") if is_number else ("-" * (width + 2)) for width, is_number in zip(widths, numeric)
        )
        + "|"
    )
    return "\n".join([line(header), rule] + [line(row) for row in rows]) + "\n"


LATEX_SPECIAL = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
}


def latex_escape(text: str) -> str:
    return "".join(LATEX_SPECIAL.get(character, character) for character in text).replace("±", r"$\pm$")


def latex_table(header: Sequence[str], rows: Sequence[Sequence[str]], numeric: Sequence[bool], title: str = "") -> str:
    """A booktabs ``tabular`` (text columns ``l``, numeric columns ``r``), with ``title`` as a comment."""
    spec = "".join("r" if is_number else "l" for is_number in numeric)
    lines = ([f"% {title}"] if title else []) + [
        rf"\begin{{tabular}}{{{spec}}}",
        r"\toprule",
        " & ".join(latex_escape(name) for name in header) + r" \\",
        r"\midrule",
    ]
    lines += [" & ".join(latex_escape(cell) for cell in row) + r" \\" for row in rows]
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def html_table(header: Sequence[str], rows: Sequence[Sequence[str]], numeric: Sequence[bool]) -> str:
    """An HTML table in a horizontally scrolling box; cells kept on one line unless classed ``txt`` (longer text,
    wraps), numbers classed ``num`` (right-aligned). Short cells carry no class: a report's tables have
    thousands of them."""

    def cell_start(text: str, is_number: bool) -> str:
        return '<td class="num">' if is_number else ("<td>" if len(text) <= 24 else '<td class="txt">')

    head = "".join(f"<th>{html.escape(name)}</th>" for name in header)
    body = "".join(
        "<tr>"
        + "".join(f"{cell_start(text, is_number)}{html.escape(text)}</td>" for text, is_number in zip(row, numeric))
        + "</tr>"
        for row in rows
    )
    return f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'


def markdown_frame(frame: pd.DataFrame) -> str:
    """:func:`markdown_table` of a DataFrame (the layout of the printed alpha table)."""
    return markdown_table(*frame_cells(frame))


def html_frame(frame: pd.DataFrame) -> str:
    """:func:`html_table` of a DataFrame."""
    return html_table(*frame_cells(frame))
