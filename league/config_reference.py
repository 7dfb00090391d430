"""Print the configuration reference: ``python -m league.config_reference > docs/configuration.md``.

Every key of a run config with its type, default and field docstring (``league.config.reference_markdown``).
"""

from __future__ import annotations

from league.cli import command_parser
from league.config import reference_markdown


def main(argv: list[str] | None = None) -> int:
    command_parser("python -m league.config_reference", __doc__.splitlines()[0]).parse_args(argv)
    print(reference_markdown(), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
