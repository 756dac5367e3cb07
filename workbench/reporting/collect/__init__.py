"""``workbench collect``: a sweep's records gathered into the collected tables, their figures and findings (sweep)."""
