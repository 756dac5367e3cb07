"""The cell and run tables: cells (number formats and the Markdown, LaTeX and HTML tables) and runs (the tidy runs
table of a sweep, its summary and the paired comparisons over replicates)."""
