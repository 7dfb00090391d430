"""The configuration reference (``docs/configuration.md``) is generated from the config models and matches them."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict

from league.config import reference_markdown, undocumented_fields

REFERENCE = Path(__file__).resolve().parents[2] / "docs" / "configuration.md"


def test_the_reference_page_is_what_the_code_generates():
    assert REFERENCE.read_text() == reference_markdown(), (
        "docs/configuration.md is stale: python -m league.config_reference > docs/configuration.md"
    )


def test_every_config_key_is_documented():
    assert undocumented_fields() == []


def test_an_undocumented_key_is_found():
    class Inner(BaseModel):
        model_config = ConfigDict(use_attribute_docstrings=True)
        size: int = 1
        """Documented."""
        bare: float = 0.5

    class Outer(BaseModel):
        """A section."""

        model_config = ConfigDict(use_attribute_docstrings=True)
        inner: Inner = Inner()
        items: list[Inner] = []
        loose: str = ""

    assert undocumented_fields(Outer) == ["items", "loose", "inner.bare", "items[].bare"]
    assert "| `bare` | `float` | `0.5` |  |" in reference_markdown(Outer)
