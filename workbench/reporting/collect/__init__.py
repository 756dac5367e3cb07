"""``workbench collect``: a sweep's records gathered into the collected tables and their findings (sweep, with the
sweep's callback that collects when it ends) and the command's arguments (command)."""
