"""The algorithm table: each record matches the library it names."""

from __future__ import annotations

import gymnasium as gym
import pytest

from bbbench.policies.sb3.algorithms import (
    SB3_ALGORITHMS,
    algorithm_of,
    by_key,
    declared_parameters,
)
from bbbench.robots.twowheel import ACTION_MODES

FLAT = "bbbench/FlatBalance-v1"


def test_every_record_names_classes_that_exist_and_keys_that_differ():
    keys = [algorithm.key for algorithm in SB3_ALGORITHMS.values()]
    assert len(set(keys)) == len(keys)
    for algorithm in SB3_ALGORITHMS.values():
        model = algorithm.model_class()
        assert model.__name__ == algorithm.model.split(":")[1]
        assert set(algorithm.action_modes) <= set(ACTION_MODES)
        assert by_key(algorithm.key) is algorithm
        default_policy = model.policy_aliases["MlpPolicy"]
        name = f"{default_policy.__module__}:{default_policy.__name__}"
        assert name in algorithm.policies, algorithm.name


def test_an_unknown_key_names_the_closest():
    with pytest.raises(ValueError, match="Did you mean 'ppo'"):
        by_key("ppp")


def test_algorithms_that_share_a_policy_class_are_told_apart_by_their_data():
    shared = "stable_baselines3.common.policies:ActorCriticPolicy"
    assert algorithm_of(shared, {"n_epochs": 10}).name == "PPO"
    assert algorithm_of(shared, {"cg_max_steps": 15}).name == "TRPO"
    assert algorithm_of(shared, {}).name == "A2C"
    assert algorithm_of("stable_baselines3.common.policies:ActorCriticCnnPolicy", {}) is None


@pytest.mark.parametrize("name", list(SB3_ALGORITHMS))
def test_declared_parameters_count_the_network_the_library_builds(name):
    """The count the zip reader refuses large networks by is the library's own."""
    algorithm = SB3_ALGORITHMS[name]
    env = gym.make(FLAT, action_mode=algorithm.action_modes[0])
    small = {} if algorithm.on_policy or algorithm.key == "ars" else {"buffer_size": 16}
    model = algorithm.model_class()("MlpPolicy", env, device="cpu", **small)
    built = sum(parameter.numel() for parameter in model.policy.parameters())
    counted = declared_parameters(
        algorithm, env.observation_space.shape, env.action_space, None, {}
    )
    env.close()
    assert counted == built
