"""Start a run in a run directory, or resume the run it holds: the containers' entrypoint.

``python -m league.start_or_resume --config cluster --run-dir /runs/cluster [--address auto]``
becomes ``league.run --config cluster --run-dir /runs/cluster`` when the directory is missing
or empty, and ``league.run --resume /runs/cluster`` once it holds a run (its ``league.db``),
a finished one included (``league.run`` then says so and exits 0). A container restarted
after a crash, a kill or a lost node therefore goes on from the run's last checkpoint instead
of refusing a directory that "exists and is not empty".

The run found must be of the config asked for (``--config`` with its ``--set`` overrides):
another one is refused, exit 2, naming the keys that differ, so a deployment whose config was
changed does not quietly continue the old run. The process then becomes ``league.run``
(``exec``), so that stop signals reach it.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from league.cli import command_parser
from league.config import ConfigError, changed_keys, load_config
from league.state.run_dir import RunDirError, read_config
from league.state.store import DB_NAME


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = command_parser(prog="python -m league.start_or_resume", description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="YAML file, or a name in configs/ (smoke, cluster, ...)")
    parser.add_argument("--run-dir", type=Path, required=True, help="the run's directory: made, or resumed")
    parser.add_argument("--address", help="address of a running Ray cluster to join (e.g. auto, host:6379)")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a config key, as league.run's --set; a resumed run must have been started with the same",
    )
    return parser.parse_args(argv)


def holds_a_run(run_dir: Path) -> bool:
    """Whether ``run_dir`` holds a run to resume (its league database), as opposed to nothing yet."""
    return (run_dir / DB_NAME).exists()


def league_run_args(config: str, run_dir: Path, overrides: list[str], address: str | None) -> list[str]:
    """``league.run``'s arguments: a new run of ``config``, or the resume of the run in ``run_dir``.

    Raises ``ConfigError`` for a config that does not load, ``RunDirError`` for a run of another config."""
    requested = load_config(config, overrides)
    joining = ["--address", address] if address else []
    if not holds_a_run(run_dir):
        # (anything else in the directory is league.run's to refuse: it never overwrites)
        return ["--config", config, "--run-dir", str(run_dir), *(f"--set={item}" for item in overrides), *joining]
    try:
        saved = read_config(run_dir)
    except RunDirError:  # a damaged or missing config.yaml: league.run --resume says what is wrong and what to do
        return ["--resume", str(run_dir), *joining]
    differing = changed_keys(saved.model_dump(mode="json"), requested.model_dump(mode="json"))
    if differing:
        raise RunDirError(
            f"{run_dir} holds a run of another config than --config {config}"
            f"{' with --set' if overrides else ''} ({', '.join(differing)} differ): "
            "give the config it was started with, or another --run-dir"
        )
    return ["--resume", str(run_dir), *joining]


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        run_args = league_run_args(args.config, args.run_dir, args.overrides, args.address)
    except (ConfigError, RunDirError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    resuming = run_args[0] == "--resume"
    print(
        f"{'resuming the run in' if resuming else 'starting a new run in'} {args.run_dir}: "
        f"python -m league.run {' '.join(run_args)}",
        file=sys.stderr, flush=True,
    )
    os.execv(sys.executable, [sys.executable, "-m", "league.run", *run_args])
    return 0  # not reached: execv replaces this process


if __name__ == "__main__":
    sys.exit(main())
