"""Self-play league training for the 3D target defense game: packages along the data flow (docs/architecture.md)."""

__version__ = "0.1.0"  # the package's one version: pyproject.toml reads it from here (dynamic)
