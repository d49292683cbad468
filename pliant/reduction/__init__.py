"""Model order reduction."""
