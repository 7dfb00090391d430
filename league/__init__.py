"""Self-play league training for the 3D target defense game: packages along the data flow (docs/architecture.md)."""

__version__ = "0.1.0"  # pyproject.toml's version; tests/test_layering.py keeps the two equal
