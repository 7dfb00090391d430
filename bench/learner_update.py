"""Seconds of one team update of the Learner, on a batch sampled with the config's settings.

Builds the algorithm of ``--config`` (the fast sampler, one torch thread), samples one
training batch of the team learner playing a (frozen, untrained) attacker, then times
``Learner.update`` on that batch ``--rounds`` times: the team's update of the team phase
(T and D share one module, so 2 rows per env step), minibatches and epochs as configured.
Each round starts from the same weights and optimizer state.

    PYTHONPATH=. .venv/bin/python bench/learner_update.py --config attacker_method2 --rounds 5

It imports only what every tree since issue 13 has, so the same script can time another
tree's Learner (``PYTHONPATH=/path/to/other/tree``). ``--profile FILE`` writes a cProfile of
the rounds. The last line reads ``update S s, CPU C s (medians of R), rows N, minibatches M``
(the CPU time of this process, less moved by other processes on a shared machine).
"""

from __future__ import annotations

import argparse
import cProfile
import copy
import statistics
import time

import ray
import torch

from league.config import load_config
from league.players import Player
from league.rllib_bridge import MatchPlan, build_config, minibatch_size, set_trainable, training_batch
from ray.rllib.utils.metrics import NUM_ENV_STEPS_SAMPLED_LIFETIME, NUM_MODULE_STEPS_TRAINED_LIFETIME

ATTACKER = Player(id=1, side="attacker", kind="learner", version=0, reward_method=2)
TEAM = Player(id=2, side="team", kind="learner", version=0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="attacker_method2")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--profile", default=None, help="write a cProfile of the timed rounds here")
    args = parser.parse_args()
    torch.set_num_threads(1)
    run = load_config(args.config, ["resources.num_env_runners=0", "resources.sampler=fast"])
    ray.init(address="local", num_cpus=1, include_dashboard=False)
    try:
        plan = MatchPlan([TEAM.modules()], [[{"attacker": ATTACKER.name}]], [[1.0]], seed=0)
        algo = build_config(run, [ATTACKER, TEAM], plan).build_algo()
        set_trainable(algo, [TEAM.name])
        runner, config = algo.env_runner, algo.config
        data = runner.sample_training_data(config.total_train_batch_size)
        batch = training_batch([data], env_steps=config.total_train_batch_size)
        [learner] = [r.get() for r in algo.learner_group.foreach_learner(lambda learner: learner)]  # the local one (num_learners=0)
        start = learner.get_state(components=["rl_module", "optimizer"])

        def update() -> tuple[float, float]:
            learner.set_state(copy.deepcopy(start))  # (a restored optimizer keeps the arrays it is given)
            began, cpu = time.perf_counter(), time.process_time()
            learner.update(
                batch=batch,
                timesteps={NUM_ENV_STEPS_SAMPLED_LIFETIME: 0, NUM_MODULE_STEPS_TRAINED_LIFETIME: 0},
                num_epochs=config.num_epochs,
                minibatch_size=minibatch_size(config, batch),
                shuffle_batch_per_epoch=config.shuffle_batch_per_epoch,
            )
            return time.perf_counter() - began, time.process_time() - cpu

        update()  # warm-up
        profiler = cProfile.Profile() if args.profile else None
        if profiler:
            profiler.enable()
        seconds, cpu_seconds = zip(*(update() for _ in range(args.rounds)))
        if profiler:
            profiler.disable()
            profiler.dump_stats(args.profile)
        rows = len(batch.policy_batches[TEAM.name])
        size = minibatch_size(config, batch)
        print("rounds (wall s):", " ".join(f"{s:.3f}" for s in seconds))
        print("rounds (CPU s):", " ".join(f"{s:.3f}" for s in cpu_seconds))
        print(
            f"update {statistics.median(seconds):.3f} s, CPU {statistics.median(cpu_seconds):.3f} s "
            f"(medians of {len(seconds)}), rows {rows}, minibatches {config.num_epochs * (rows // size)}"
        )
        algo.stop()
    finally:
        ray.shutdown()


if __name__ == "__main__":
    main()
