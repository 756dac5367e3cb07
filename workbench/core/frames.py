"""The number types frames are kept in: ``dataset.dtype``'s choices (the schema's rule) and the arrays
:mod:`workbench.numerics.frames` makes of them, named once for both."""

FRAME_DTYPES = ("float64", "float32")
"""``dataset.dtype``: float64 (the default) or float32 (half the memory, to float32 rounding)."""
