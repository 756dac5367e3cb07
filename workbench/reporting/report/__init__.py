"""``workbench report``: the command (command), the report of a run (run) and of a sweep (sweep), their sections
(sections, bases), figures (run_figures, faces) and the arrays rebuilt for them (data), the left/right pairs of hand
shapes (sides) and the documents rendered from ``templates/`` with ``static/`` (page)."""
