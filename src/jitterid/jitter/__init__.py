"""jitter."""
