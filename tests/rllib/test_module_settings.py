"""Module settings: typed at both ends of RLlib's ``model_config`` dict, no key misspelt or missing."""

import pytest
import torch

from league.config import RunConfig
from league.rllib.bridge import learner_settings, learner_spec, load_module, scripted_spec
from league.rllib.module_settings import ActorCriticSettings, ScriptedSettings
from league.rllib.modules import ActorCriticModule, ScriptedModule

torch.set_num_threads(1)

RUN = RunConfig(
    name="settings",
    ppo={"hidden": [16, 8], "team_reward": "shared", "targeter_shaping": 2.0, "attacker_win_reward": 50.0},
    resources={"sampler": "fast"},
    league={"frozen_players_explore": False},
)


def team_model_config() -> dict:
    return learner_spec(RUN, "team").model_config


def test_a_learners_settings_survive_the_model_config_dict():
    for side, method in (("attacker", 3), ("team", None)):
        settings = learner_settings(RUN, side, method)
        assert ActorCriticSettings.from_model_config(settings.as_model_config()) == settings
        assert learner_spec(RUN, side, method).build().settings == settings
    module = scripted_spec(RUN, "targeter", "avoid_attacker").build()
    assert isinstance(module, ScriptedModule)
    assert module.settings == ScriptedSettings(agent="targeter", name="avoid_attacker", game=RUN.game, actor_inputs=module.actor_inputs)


def test_the_team_is_paid_as_the_run_says():
    team, attacker = learner_settings(RUN, "team"), learner_settings(RUN, "attacker", 2)
    assert (team.team_reward, team.shaping_of("targeter"), team.shaping_of("defender"), team.attacker_win_reward) == (
        "shared", 2.0, 0.0, 0.0,
    )
    assert (attacker.team_reward, attacker.shaping_of("targeter"), attacker.attacker_win_reward) == ("own", 0.0, 50.0)
    assert attacker.shaping_of("attacker") == 0.0 and not team.explore_when_frozen


def test_a_misspelt_setting_is_an_error_naming_it():
    config = team_model_config()
    config["explore_when_forzen"] = config.pop("explore_when_frozen")
    with pytest.raises(ValueError, match=r"unknown key 'explore_when_forzen', missing key 'explore_when_frozen'"):
        ActorCriticSettings.from_model_config(config)
    # Where RLlib builds the module from its spec, too.
    spec = learner_spec(RUN, "team")
    spec.model_config = config
    with pytest.raises(ValueError, match="explore_when_forzen"):
        spec.build()


def test_a_misspelt_pay_setting_is_an_error_naming_it():
    # The pay settings are `league.rollout.training_reward.TrainingPay`'s, flat in the same dict.
    config = team_model_config()
    config["targeter_shapng"] = config.pop("targeter_shaping")
    with pytest.raises(ValueError, match=r"unknown key 'targeter_shapng', missing key 'targeter_shaping'"):
        ActorCriticSettings.from_model_config(config)


def test_a_missing_or_ill_typed_setting_is_an_error_naming_it():
    config = team_model_config()
    del config["bf16"]
    with pytest.raises(ValueError, match=r"missing key 'bf16'"):
        ActorCriticSettings.from_model_config(config)
    with pytest.raises(ValueError, match="critic"):
        ActorCriticSettings.from_model_config({**team_model_config(), "critic": "globl"})
    with pytest.raises(ValueError, match=r"unknown key 'reward_method'"):
        ScriptedSettings.from_model_config({**scripted_spec(RUN, "attacker", "lead_intercept").model_config, "reward_method": 2})


def test_rllibs_own_model_config_keys_are_let_through():
    # PPO adds `vf_share_layers` to the model_config of every module the algorithm builds.
    settings = ActorCriticSettings.from_model_config({**team_model_config(), "vf_share_layers": False})
    assert settings == learner_settings(RUN, "team")


def test_a_module_saved_before_the_settings_were_typed_loads():
    # The dict as `learner_spec` wrote it before (hidden a list, the game a dict) and as the
    # algorithm saved it (with RLlib's key): checkpoints and players/ directories hold such dicts.
    saved = {
        "actor_inputs": 22, "critic": "local", "hidden": [16, 8], "bf16": False, "reward_method": 2,
        "gamma": 0.99, "lambda_": 0.95, "targeter_shaping": 0.0, "defender_shaping": 0.0,
        "attacker_win_reward": 50.0, "team_reward": "own", "explore_when_frozen": False, "prior": "none",
        "heading_cosines": False, "game": RUN.game.model_dump(), "vf_share_layers": False,
    }
    settings = ActorCriticSettings.from_model_config(saved)
    assert settings == learner_settings(RUN, "attacker", 2).model_copy(update={"actor_inputs": 22})


def test_a_saved_module_loads_with_its_settings(tmp_path):
    module = learner_spec(RUN, "attacker", 3).build()
    module.save_to_path(str(tmp_path / "m"))
    loaded = load_module(tmp_path / "m")
    assert isinstance(loaded, ActorCriticModule) and loaded.settings == module.settings


def test_a_players_saved_module_of_a_run_loads(tiny_run):
    for path in sorted((tiny_run / "players").iterdir()):
        module = load_module(path)
        assert module.settings.reward_method == (2 if path.name.startswith("attacker") else None)
