"""What the commands (``python -m league.run``, ``league.status``, ...) share: argument types and ``--version``.

A helper for commands, not a command: library code does not import it.
"""

from __future__ import annotations

import argparse

import league


def count(minimum: int):
    """An argparse type: an integer of at least ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    return parse


def command_parser(prog: str, description: str, **kwargs) -> argparse.ArgumentParser:
    """A command's parser, with ``--version`` (the package's version)."""
    made = argparse.ArgumentParser(prog=prog, description=description, **kwargs)
    made.add_argument("--version", action="version", version=f"%(prog)s {league.__version__}")
    return made
