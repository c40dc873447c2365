"""The Gymnasium environment: API conformance, determinism, a short episode."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import continuum_sim.env as cenv

STAGES = ("initial",)


@pytest.fixture(scope="module")
def env():
    environment = gym.make(cenv.ENV_ID, stages=STAGES)
    yield environment
    environment.close()


def test_registered_and_passes_gymnasiums_checker(env):
    assert isinstance(env.unwrapped, cenv.SampleRemovalEnv)
    check_env(env.unwrapped, skip_render_check=True)


def _vector(obs: dict) -> np.ndarray:
    return np.concatenate([np.ravel(obs[key]).astype(float) for key in sorted(obs)])


def _rollout(env, seed: int, n: int) -> np.ndarray:
    """Observations and rewards of ``n`` random-action steps, flattened."""
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    out = [_vector(obs)]
    for _ in range(n):
        obs, reward, terminated, _, _ = env.step(env.action_space.sample())
        out += [_vector(obs), np.array([reward])]
        if terminated:
            break
    return np.concatenate(out)


def test_deterministic_under_a_seed(env):
    first = _rollout(env, 3, 6)
    np.testing.assert_array_equal(first, _rollout(env, 3, 6))
    assert not np.array_equal(first, _rollout(env, 4, 6))  # another seed: other random actions


def test_zero_action_episode_succeeds_and_tracks_the_plan(env):
    obs, info = env.reset(seed=0)
    steps, rewards = 0, []
    while True:
        obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
        rewards.append(reward)
        steps += 1
        assert not truncated
        if terminated:
            break
    assert info["success"] and info["failure"] is None
    assert steps == int(np.ceil(env.unwrapped.n_ticks / env.unwrapped.ticks_per_step))
    assert np.all(np.linalg.norm(obs["tool_error"], axis=1) < 2e-3)  # within 2 mm of the plan
    assert obs["progress"][0] == pytest.approx(1.0, abs=1e-2)
