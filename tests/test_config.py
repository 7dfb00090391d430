"""Run configs (``league.config``): bad values are errors naming the key, every shipped config
loads, and ``--set`` overrides name where a bad key came from."""

import pytest

from league.config import CONFIG_DIR, ConfigError, changed_keys, load_config


def write(tmp_path, text):
    path = tmp_path / "run.yaml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(
    "text, key",
    [
        ("name: x\nppo: {learning_rate: 0.1}\n", "ppo.learning_rate"),
        ("name: x\nppo: {train_batch_size: lots}\n", "ppo.train_batch_size"),
        ("name: x\ngame: {v_attacker: 0.1}\n", "v_attacker"),
        ("name: x\nppo: {train_batch_size: 100, minibatch_size: 200}\n", "minibatch_size"),
        ("name: x\nleague: {scripted_attackers: [teleport]}\n", "teleport"),
        ("name: x\nleague: {mode: protocol}\n", "phases"),
        ("seed: 1\n", "name"),
        ("name: x\nresources: {sampler: turbo}\n", "resources.sampler"),
        ("name: x\nevaluation: {custom_resources_per_worker: {evaluator: many}}\n", "custom_resources_per_worker"),
        ("name: x\nppo: {team_gamma: 1.5}\n", "ppo.team_gamma"),
        # RLlib's own GAE (batched and standard samplers) has one discount for every module.
        ("name: x\nppo: {team_gamma: 0.999}\nresources: {sampler: batched}\n", "team_gamma"),
        ("name: x\nppo: {minibatch_counts: env_steps}\nresources: {sampler: standard}\n", "minibatch_counts"),
        ("name: x\nppo: {minibatch_counts: games}\n", "ppo.minibatch_counts"),
        ("name: x\nppo: {team_num_epochs: 2}\nresources: {sampler: standard}\n", "ppo.team_num_epochs needs resources.sampler: fast"),
        ("name: x\nppo: {team_num_epochs: 0}\n", "ppo.team_num_epochs"),
        ("name: x\nppo: {targeter_shaping: -1}\n", "ppo.targeter_shaping"),
        ("name: x\nppo: {targeter_shaping: 3}\nresources: {sampler: batched}\n", "targeter_shaping"),
        ("name: x\nppo: {defender_shaping: 3}\nresources: {sampler: batched}\n", "defender_shaping"),
        ("name: x\nppo: {attacker_win_reward: 70}\nresources: {sampler: standard}\n", "attacker_win_reward"),
        ("name: x\nppo: {team_reward: shared}\nresources: {sampler: standard}\n", "team_reward"),
        ("name: x\nppo: {bf16: true}\nresources: {sampler: batched}\n", "bf16"),  # RLlib's own loss has no autocast
        ("name: x\nppo: {compile_loss: true}\nresources: {sampler: standard}\n", "ppo.compile_loss needs resources.sampler: fast"),
        ("name: x\nppo: {compile_loss: sometimes}\n", "ppo.compile_loss"),
        ("name: x\nppo: {team_reward: mine}\n", "ppo.team_reward"),
        ("name: x\nleague: {frozen_players_explore: false}\nresources: {sampler: standard}\n", "frozen_players_explore"),
        ("name: x\nppo: {lr_schedule: [[100, 0.001]]}\n", "lr_schedule"),
        ("name: x\nppo: {attacker_prior: lead_intercept}\ngame: {observation: paper}\n", "attacker_prior"),
        ("name: x\nppo: {attacker_prior: pure_pursuit}\n", "ppo.attacker_prior"),
        ("name: x\nppo: {team_prior: straight+pure_pursuit}\ngame: {action_mode: absolute}\n", "team_prior"),
        ("name: x\nppo: {attacker_heading_cosines: true}\ngame: {observation: paper}\n", "attacker_heading_cosines"),
        ("name: x\nppo: {attacker_scripted_turns: true}\ngame: {observation: paper}\n", "attacker_scripted_turns"),
        ("name: x\nppo: {attacker_prior: apollonius}\ngame: {observation: paper}\n", "attacker_prior"),
        ("name: x\nppo: {attacker_residual_penalty: 0.1}\n", "attacker_residual_penalty needs ppo.attacker_prior"),
        ("name: x\nppo: {attacker_residual_penalty: -1, attacker_prior: lead_intercept}\n", "ppo.attacker_residual_penalty"),
        ("name: x\nppo: {attacker_residual_penalty_gate: until_targeter_turns}\n", "needs game.attacker_memory"),
        ("name: x\nppo: {lr_schedule: [[0, 0.001], [0, 0.0001]]}\n", "lr_schedule"),
        ("name: x\nresources: {sample_ahead: true}\n", "resources.sample_ahead needs resources.num_env_runners >= 1"),
        ("name: x\nresources: {sample_ahead: true, num_env_runners: 1, sampler: batched}\n", "resources.sample_ahead"),
    ],
)
def test_invalid_config_names_the_key(tmp_path, text, key):
    with pytest.raises(ConfigError, match=key):
        load_config(write(tmp_path, text))


def test_every_shipped_config_is_valid():
    names = {path.stem for path in CONFIG_DIR.glob("*.yaml")}
    assert {"smoke", "selfplay_league", "cluster"} | {f"attacker_method{n}{paper}" for n in (1, 2, 3) for paper in ("", "_paper")} <= names
    for name in names:
        assert load_config(name).name == name


def test_the_cluster_config_is_the_smoke_league_placed_on_nodes():
    smoke, cluster = (load_config(name).model_dump(mode="json") for name in ("smoke", "cluster"))
    placement = ("name", "resources.", "evaluation.workers", "evaluation.cpus_per_worker", "evaluation.custom_resources")
    assert [key for key in changed_keys(smoke, cluster) if not key.startswith(placement)] == []
    assert cluster["resources"]["custom_resources_per_env_runner"] == {"sampler": 1}
    assert cluster["evaluation"]["custom_resources_per_worker"] == {"evaluator": 1}


def test_set_overrides_and_bad_yaml(tmp_path):
    config = load_config("smoke", ["ppo.lr=0.001", "game.attacker_reward=3"])
    assert config.ppo.lr == 0.001 and config.game.attacker_reward == 3
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(write(tmp_path, "name: [x\n"))
    with pytest.raises(ConfigError, match="not found"):
        load_config("no_such_config")
    with pytest.raises(ConfigError, match="key=value"):
        load_config("smoke", ["ppo.lr"])


def test_a_bad_key_given_with_set_is_reported_as_coming_from_set(tmp_path):
    with pytest.raises(ConfigError) as err:
        load_config("smoke", ["ppo.lrr=1"])
    assert str(err.value).startswith("--set ppo.lrr=1: ppo.lrr: ") and "smoke.yaml" not in str(err.value)
    bad_file = write(tmp_path, "name: x\nppo: {lrr: 1}\n")
    with pytest.raises(ConfigError, match=r"run\.yaml: ppo\.lrr: "):  # a key from the file still names the file
        load_config(bad_file, ["seed=3"])
