"""Export a league player's policy for use without Ray: torch.export, TorchScript or ONNX.

``python -m league.export --run-dir DIR --player latest-attacker --format torchscript --out attacker.pt``

The exported module takes the observation the env gives the agent (PettingZoo layout,
``envs.observations``; for the team policy including its role one-hot) as a float32
batch ``(B, size)`` and returns the deterministic action ``(B, 2)``: the mean of the
Gaussian policy, exactly what the league plays in evaluation. Nothing else is applied
on the way in RLlib (no observation filter, no action normalisation); the env clips
actions into its box, so the effective action is ``clamp(action, low, high)``.

Formats: ``export`` writes a ``torch.export`` ``ExportedProgram`` (``.pt2``, load with
``torch.export.load(path).module()``), the format torch develops further; ``torchscript``
(``torch.jit.load``) is kept for the users who ask for it, though torch 2.13 marks
``torch.jit`` deprecated; ``onnx`` for other runtimes. The batch dimension is dynamic in all three.

The metadata travels inside the file (``.pt2`` and TorchScript extra file ``metadata.json``;
ONNX ``metadata_props``): observation and action layout, game parameters, player, versions.

``--player nash-attacker`` or ``nash-team`` (``@ITERATION`` for that iteration's meta-game)
exports the side's Nash mixture as one module of every member (``ExportedMixture``):
``forward(observation, seed, game)`` returns ``(action, member)``, the action of the member
drawn for the row's ``(seed, game)``, the same member ``league.evaluate --mixture-seed`` draws
for that fixed game. A mixture with a scripted member is refused (exit 2), naming it: scripted
players act on the game's exact state, not on the observation.
"""

from __future__ import annotations

import sys
from pathlib import Path

from league.cli import command_parser
from league.evaluation.exported_policy import FORMATS, ExportError, build, export


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python -m league.export", description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--player", required=True, help="player id or name, latest-attacker or latest-team, or a mixture nash-attacker, nash-team[@ITERATION]")
    parser.add_argument("--format", choices=FORMATS, default="torchscript")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if args.out.is_dir():
        print(f"error: --out {args.out} is a directory; give a file name, e.g. {args.out / 'policy.pt'}", file=sys.stderr)
        return 2
    try:
        policy, info = build(args.run_dir, args.player)
        export(policy, info, args.format, args.out)
    except ExportError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except ImportError as err:
        print(f"error: {err}; ONNX export needs the extra: pip install -e '.[onnx]'", file=sys.stderr)
        return 2
    print(f"exported {info['player']['name']} ({args.format}) to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
