"""``workbench export``: a run's bases and weights as glTF, OBJ and Live Link files: the bases and their playback
targets (bases), the takes and their weight curves (takes), the files of one export (run) and the command (command)."""
