"""Backends as another package would ship them: found by entry point, registered on import."""
