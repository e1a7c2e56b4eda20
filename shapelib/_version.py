"""The package version (one place; read by the engine's stores and the CLI)."""

__version__ = "0.2.0"
