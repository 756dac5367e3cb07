"""The workbench's own error type.

Every check at a boundary raises :class:`WorkbenchError` (a ``ValueError``) whose message names the input and
the rule it broke; the command line prints that message as one line.
"""


class WorkbenchError(ValueError):
    """Bad input or configuration: the message names the file, field or parameter and the rule it broke."""


def single_line(text) -> str:
    """A message as one line: its non-empty lines joined with '; ' (a library's text may span several)."""
    return "; ".join(line.strip() for line in str(text).splitlines() if line.strip())
