"""The workbench's own error type.

Every check at a boundary raises :class:`WorkbenchError` (a ``ValueError``) whose message names the input and
the rule it broke; the command line prints that message as one line.
"""


class WorkbenchError(ValueError):
    """Bad input or configuration: the message names the file, field or parameter and the rule it broke."""


def single_line(text) -> str:
    """A message as one line: its non-empty lines joined with '; ' (a library's text may span several)."""
    return "; ".join(line.strip() for line in str(text).splitlines() if line.strip())


def check_utf8(text: str, what: str) -> None:
    """Refuse a name or path that is not valid UTF-8 (Python keeps such bytes as lone surrogates, which no file of
    a record can hold): one line naming ``what`` and the first bad byte, before anything is computed.

    Raises
    ------
    WorkbenchError
    """
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as error:
        character = text[error.start]
        byte = f"0x{ord(character) - 0xDC00:02x}" if 0xDC80 <= ord(character) <= 0xDCFF else repr(character)
        shown = text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
        raise WorkbenchError(f"{what} '{shown}' is not valid UTF-8 (byte {byte} at position {error.start}); "
                             "name files, folders and settings in UTF-8") from None
