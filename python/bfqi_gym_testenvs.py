"""Misbehaving gymnasium envs for bfqi-ga's failure tests (tests/gym_failures.rs, test_worker.py).

Each of the first four is cart-pole until step `at` of an episode (counted from its reset), then
(only while the file `flag` exists, when a flag is given):
- `BfqiHang-v0` sleeps far beyond any timeout,
- `BfqiCrash-v0` kills its own process (exit code 7),
- `BfqiNan-v0` returns a NaN observation,
- `BfqiRaise-v0` raises an exception.

`BfqiStateObs-v0` (kwargs `inner`, an env id, and `state_dim`) is not faulty: its observation is
the inner env's internal `state` (float64) followed by the inner env's own observation, so the
tests can compare gymnasium's dynamics with the built-in ones from the exact state.

Use them as `"id": "bfqi_gym_testenvs:BfqiHang-v0"` with this folder on PYTHONPATH: gymnasium
imports the module before the `:`, which registers them.
"""

import os
import time

import gymnasium as gym
import numpy as np
from gymnasium.envs.classic_control.cartpole import CartPoleEnv
from gymnasium.envs.registration import register


class _Faulty(CartPoleEnv):
    def __init__(self, at=5, flag=None, **kwargs):
        super().__init__(**kwargs)
        self.at = at
        self.flag = flag
        self.t = 0

    def reset(self, *, seed=None, options=None):
        self.t = 0
        return super().reset(seed=seed, options=options)

    def step(self, action):
        self.t += 1
        if self.t >= self.at and (self.flag is None or os.path.exists(self.flag)):
            return self.fault(super().step(action))
        return super().step(action)


class HangEnv(_Faulty):
    def fault(self, out):
        time.sleep(3600)
        return out


class CrashEnv(_Faulty):
    def fault(self, out):
        os._exit(7)


class NanEnv(_Faulty):
    def fault(self, out):
        obs, r, term, trunc, info = out
        obs = np.array(obs)
        obs[1] = np.nan
        return obs, r, term, trunc, info


class RaiseEnv(_Faulty):
    def fault(self, out):
        raise RuntimeError("the simulator lost its state")


for _name, _cls in [("Hang", "HangEnv"), ("Crash", "CrashEnv"), ("Nan", "NanEnv"), ("Raise", "RaiseEnv")]:
    register(id=f"Bfqi{_name}-v0", entry_point=f"bfqi_gym_testenvs:{_cls}", max_episode_steps=500)


class NoRenderEnv(CartPoleEnv):
    """Cart-pole that offers rgb_array rendering but whose render() fails, as one without pygame."""

    def render(self):
        raise RuntimeError("no display for render()")


register(id="BfqiNoRender-v0", entry_point="bfqi_gym_testenvs:NoRenderEnv", max_episode_steps=500)


class StateObs(gym.Wrapper):
    """The inner env's internal state, then its own observation, as one float64 observation."""

    def __init__(self, env, state_dim):
        super().__init__(env)
        d = int(np.prod(env.observation_space.shape))
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (state_dim + d,), np.float64)

    def _obs(self, obs):
        state = np.asarray(self.env.unwrapped.state, dtype=np.float64).reshape(-1)
        return np.concatenate([state, np.asarray(obs, dtype=np.float64).reshape(-1)])

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return self._obs(obs), info

    def step(self, action):
        obs, r, term, trunc, info = self.env.step(action)
        return self._obs(obs), r, term, trunc, info


def make_state_obs(inner="CartPole-v1", state_dim=4, **kwargs):
    return StateObs(gym.make(inner, **kwargs), state_dim)


register(id="BfqiStateObs-v0", entry_point=make_state_obs)
