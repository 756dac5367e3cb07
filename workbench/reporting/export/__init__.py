"""``workbench export``: a run's bases and weights as glTF, OBJ and Live Link files (run)."""
