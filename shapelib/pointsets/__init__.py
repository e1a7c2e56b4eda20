"""Point sets of any size (no landmark correspondence)."""
