"""The package version, in one place (``pyproject.toml`` reads it; ``fitting`` re-uses it)."""

__version__ = "0.1.0"
