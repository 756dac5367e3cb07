"""The text a run prints: its alpha tables fitted to the terminal, its header, regime and conditioning lines and the
sentence saying whether the paper's claims were reproduced (run)."""
