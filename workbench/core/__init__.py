"""The ground every layer stands on: errors and their one line, files written atomically, interrupts, progress,
optional extras and the machine's resources. Imports nothing else of the workbench."""
