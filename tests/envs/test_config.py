"""Invalid game configs fail early with a message naming the key."""

import pytest
from pydantic import ValidationError

from envs.config import GameConfig
from envs.pettingzoo_env import TargetDefenseEnv
from envs.rllib_env import TargetDefenseMultiAgentEnv


@pytest.mark.parametrize(
    "overrides, key",
    [
        ({"v_attacker": 0.1}, "v_attacker"),
        ({"v_attacker": 0.13}, "v_attacker"),  # equal speeds: A could never catch T
        ({"attacker_capture_radius": -0.1}, "attacker_capture_radius"),
        ({"terminal_radius": 0.0}, "terminal_radius"),
        ({"capture_radius": 0.2}, "capture_radius"),  # unknown key
        ({"attacker_reward": 4}, "attacker_reward"),
        ({"observation": "pixels"}, "observation"),
        ({"scenario": "nowhere"}, "scenario"),
        ({"v_targeter": "fast"}, "v_targeter"),
    ],
)
def test_invalid_config_names_the_key(overrides, key):
    with pytest.raises(ValidationError, match=key):
        GameConfig(**overrides)


def test_adapters_validate_their_config():
    with pytest.raises(ValidationError, match="bogus"):
        TargetDefenseEnv(bogus=1)
    with pytest.raises(ValidationError, match="v_attacker"):
        TargetDefenseMultiAgentEnv({"v_attacker": 0.01})


def test_defaults_follow_the_paper():
    config = GameConfig()
    assert config.speeds == (0.18, 0.13, 0.18)
    assert config.attacker_radius == 0.18 and config.defender_radius == 0.18
    assert config.terminal_sphere_radius == 0.13
    assert (config.w_t1, config.w_t2, config.overchase_gamma, config.axis_length) == (0.6, 0.4, 1.08, 0.1)


@pytest.mark.parametrize(
    "override, named",
    [
        ("nosuch.key=1", "--set nosuch.key=1: nosuch: Extra inputs are not permitted"),
        ("ppo.gamma.x=1", "--set ppo.gamma.x=1: ppo.gamma:"),  # a key the file does not set
        ("ppo.lr.x=1", "--set ppo.lr.x: 'lr' is not a section"),  # one it sets
        ("ppo.minibatch_size=999999", "--set ppo.minibatch_size=999999: (top level): Value error, ppo.minibatch_size"),
        ("seeed=1", "(did you mean seed?)"),
        ("ppo.hiden=[8]", "(did you mean ppo.hidden?)"),
    ],
)
def test_a_set_mistake_is_blamed_on_the_set_not_the_file(override, named):
    from league.config import ConfigError, load_config

    with pytest.raises(ConfigError) as raised:
        load_config("smoke", [override])
    assert named in str(raised.value)
    assert "smoke.yaml" not in str(raised.value)
