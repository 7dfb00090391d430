"""Seconds of one team update of the Learner: ``LeaguePPOLearner``'s against RLlib's own.

Builds the algorithm of ``--config`` (the fast sampler, one torch thread), samples one
training batch of the team learner playing a (frozen, untrained) attacker, then times, in
turn, ``--rounds`` times each, the two updates of that batch (the team's update of the team
phase: T and D share one module, so 2 rows per env step; minibatches and epochs as
configured), each from the same weights and optimizer state:

* ``rllib``: RLlib's ``Learner.update`` with RLlib's Adam (per-tensor steps), as the
  Learner updated before it had an update of its own;
* ``league``: ``LeaguePPOLearner.update`` (its Adam steps in foreach passes).

Both take the same gradient steps (``tests/rllib/test_fast_path.py``); one process runs both, so
a shared machine's load moves both alike. With ``--against bf16`` the first arm is instead
``bf16``: ``LeaguePPOLearner.update`` with ``ppo.bf16`` (float32 where the CPU has no native
bf16; the bench says which); with ``--against compile`` it is ``compile``: ``LeaguePPOLearner.update``
with ``ppo.compile_loss`` (its loss, forward and backward, under ``torch.compile``), whose
first update compiles (its seconds printed).

    PYTHONPATH=. .venv/bin/python bench/learner_update.py --config attacker_method2 --rounds 8
    PYTHONPATH=. .venv/bin/python bench/learner_update.py --against bf16 --set 'ppo.team_hidden=[256, 256]'
    PYTHONPATH=. .venv/bin/python bench/learner_update.py --against compile --config selfplay_league

``--profile FILE`` writes a cProfile of the ``league`` rounds. The last line reads ``league
L s, rllib R s, league/rllib Q (medians of N rounds; CPU: ...)``: wall seconds, and the CPU
seconds of this process, which other processes on a shared machine move less.
"""

from __future__ import annotations

import argparse
import copy
import cProfile
import statistics
import time

import ray
import torch

from league.config import load_config
from league.core.players import Player
from league.core.match_plan import MatchPlan
from league.rllib.algorithm import COMPILED_LOSS, minibatch_size, training_batch
from league.rllib.bridge import build_config, set_trainable
from league.rllib.compat import native_bf16
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.utils.metrics import NUM_ENV_STEPS_SAMPLED_LIFETIME, NUM_MODULE_STEPS_TRAINED_LIFETIME

ATTACKER = Player(id=1, side="attacker", kind="learner", version=0, reward_method=2)
TEAM = Player(id=2, side="team", kind="learner", version=0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="attacker_method2")
    parser.add_argument("--rounds", type=int, default=8)
    parser.add_argument("--profile", default=None, help="write a cProfile of the league rounds here")
    parser.add_argument("--against", choices=["rllib", "bf16", "compile"], default="rllib",
                        help="the other arm: RLlib's update, ours with ppo.bf16, or ours with its loss compiled")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    torch.set_num_threads(1)
    run = load_config(args.config, ["resources.num_env_runners=0", "resources.sampler=fast", *args.overrides])
    if args.against == "bf16":
        print(f"native bf16 on this CPU: {native_bf16()}")
    ray.init(address="local", num_cpus=1, include_dashboard=False)
    try:
        plan = MatchPlan([TEAM.modules()], [[{"attacker": ATTACKER.name}]], [[1.0]], seed=0)
        algo = build_config(run, [ATTACKER, TEAM], plan).build_algo()
        set_trainable(algo, [TEAM.name])
        config = algo.config
        data = algo.env_runner.sample_training_data(config.total_train_batch_size)
        batch = training_batch([data], env_steps=config.total_train_batch_size)
        size = minibatch_size(config, batch)
        [learner] = [r.get() for r in algo.learner_group.foreach_learner(lambda learner: learner)]  # the local one
        start = copy.deepcopy(learner.get_state(components=["rl_module", "optimizer"]))
        profiler = cProfile.Profile() if args.profile else None

        def update(arm: str) -> tuple[float, float]:
            learner.set_state(copy.deepcopy(start))  # (a restored optimizer keeps the arrays it is given)
            learner.module.set_state(start["rl_module"])
            for group in learner.get_optimizer(TEAM.name).param_groups:
                group["foreach"] = arm != "rllib"  # RLlib's Adam steps tensor by tensor
            team = learner.module[TEAM.name]
            team.settings = team.settings.model_copy(update={"bf16": arm == "bf16"})
            learner.config.learner_config_dict[COMPILED_LOSS] = arm == "compile"
            method = PPOTorchLearner.update if arm == "rllib" else type(learner).update
            fresh = training_batch([data], env_steps=config.total_train_batch_size)  # RLlib's shuffles it in place
            if profiler and arm == "league":
                profiler.enable()
            began, cpu = time.perf_counter(), time.process_time()
            method(
                learner,
                batch=fresh,
                timesteps={NUM_ENV_STEPS_SAMPLED_LIFETIME: 0, NUM_MODULE_STEPS_TRAINED_LIFETIME: 0},
                num_epochs=config.num_epochs,
                minibatch_size=size,
                shuffle_batch_per_epoch=config.shuffle_batch_per_epoch,
            )
            wall, cpu = time.perf_counter() - began, time.process_time() - cpu
            if profiler:
                profiler.disable()
            return wall, cpu

        arms = (args.against, "league")
        for arm in arms:  # warm-up
            wall, _ = update(arm)
            print(f"{arm}: first update {wall:.1f} s" + (" (compiling)" if arm == "compile" else ""))
        times = {arm: [] for arm in arms}
        for _ in range(args.rounds):
            for arm in arms:
                times[arm].append(update(arm))
        if profiler:
            profiler.dump_stats(args.profile)
        rows = len(batch.policy_batches[TEAM.name])
        print(f"rows {rows}, minibatches of {size}: {config.num_epochs * -(-rows // size)}")
        for arm in arms:
            walls, cpus = (" ".join(f"{t[which]:.3f}" for t in times[arm]) for which in (0, 1))
            print(f"{arm} wall s: {walls} | CPU s: {cpus}")

        def medians(which: int) -> str:
            league, other = (statistics.median(t[which] for t in times[arm]) for arm in ("league", args.against))
            ratios = [a[which] / b[which] for a, b in zip(times["league"], times[args.against])]
            return (
                f"league {league:.3f} s, {args.against} {other:.3f} s, league/{args.against} {statistics.median(ratios):.2f} "
                f"(per round {min(ratios):.2f} to {max(ratios):.2f})"
            )

        print(f"{medians(0)} (medians of {args.rounds} rounds; CPU: {medians(1)})")
        algo.stop()
    finally:
        ray.shutdown()


if __name__ == "__main__":
    main()
