"""3D plot of one episode's trajectories (PNG).

``python -m envs.render --attacker lead_intercept --team scripted --seed 3 --out episode.png``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display on training machines
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from envs.agents import AGENTS, ATTACKER, DEFENDER, TARGETER, Outcome
from envs.config import GameConfig
from envs.match import play, scripted_players
from envs.scenarios import SCENARIO_SETS, sample_positions
from envs.scripted import PAPER_TEAM, PLAYERS

COLOURS = {ATTACKER: "tab:red", TARGETER: "tab:blue", DEFENDER: "tab:green"}


def plot_episode(trajectory: np.ndarray, outcome: Outcome, config: GameConfig, title: str, out: Path) -> None:
    """Save the paths ``(steps + 1, 3, 3)`` with starts, terminal sphere and the ending event."""
    fig = episode_figure(trajectory, outcome, config, title)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def episode_image(trajectory: np.ndarray, outcome: Outcome, config: GameConfig, title: str) -> np.ndarray:
    """The picture of ``plot_episode`` as an RGB array ``(height, width, 3)`` of uint8 (PettingZoo's ``rgb_array``)."""
    fig = episode_figure(trajectory, outcome, config, title)
    fig.set_dpi(110)
    fig.canvas.draw()
    # The Agg backend (set above) gives the figure an Agg canvas; matplotlib types it as the base canvas.
    image = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()  # type: ignore[attr-defined]
    plt.close(fig)
    return image


def episode_figure(trajectory: np.ndarray, outcome: Outcome, config: GameConfig, title: str) -> Figure:
    """The matplotlib figure of ``plot_episode``."""
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    for agent in (ATTACKER, TARGETER, DEFENDER):
        path = trajectory[:, agent]
        ax.plot(*path.T, color=COLOURS[agent], label=AGENTS[agent])
        ax.scatter(*path[0], color=COLOURS[agent], marker="o", s=40, label=f"{AGENTS[agent]} start")
    u, v = np.mgrid[0 : 2 * np.pi : 20j, 0 : np.pi : 10j]
    r = config.terminal_sphere_radius
    ax.plot_wireframe(r * np.cos(u) * np.sin(v), r * np.sin(u) * np.sin(v), r * np.cos(v), color="grey", lw=0.5)
    ax.scatter(0, 0, 0, color="black", marker="*", s=80, label="terminal")
    end = trajectory[-1]
    if outcome == Outcome.CAPTURED:
        ax.scatter(*end[TARGETER], color="black", marker="x", s=120, label="capture of T")
    elif outcome == Outcome.ATTACKER_INTERCEPTED:
        ax.scatter(*end[ATTACKER], color="black", marker="x", s=120, label="capture of A")
    # Equal axes so that turns and the terminal sphere keep their true shape.
    points = np.vstack((trajectory.reshape(-1, 3), np.zeros((1, 3))))
    centre = (points.max(axis=0) + points.min(axis=0)) / 2
    half = max(np.max(points.max(axis=0) - points.min(axis=0)) / 2, r)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title(f"{title}\noutcome: {outcome.label} after {len(trajectory) - 1} steps" if outcome != Outcome.RUNNING
                 else f"{title}\nafter {len(trajectory) - 1} steps")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return fig


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Plot one scripted episode in 3D.")
    parser.add_argument("--attacker", default="lead_intercept", choices=sorted(PLAYERS["attacker"]))
    parser.add_argument("--team", default="scripted", choices=["scripted"], help="scripted: the paper's team")
    parser.add_argument("--targeter", choices=sorted(PLAYERS["targeter"]), help="override the team's targeter")
    parser.add_argument("--defender", choices=sorted(PLAYERS["defender"]), help="override the team's defender")
    parser.add_argument("--scenario", default="default", choices=sorted(SCENARIO_SETS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("episode.png"))
    args = parser.parse_args(argv)
    config = GameConfig(scenario=args.scenario)
    targeter = args.targeter or PAPER_TEAM["targeter"]
    defender = args.defender or PAPER_TEAM["defender"]
    positions = sample_positions(config.scenario, np.random.default_rng(args.seed), 1)
    result = play(config, scripted_players(args.attacker, targeter, defender), positions, record=True)
    trajectory = np.stack(result.trajectory)[:, 0]
    outcome = Outcome(int(result.outcome[0]))
    title = f"A {args.attacker} vs T {targeter} + D {defender}, seed {args.seed}"
    plot_episode(trajectory, outcome, config, title, args.out)
    print(f"{outcome.label} after {result.steps[0]} steps -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
