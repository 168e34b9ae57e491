"""Misbehaving gymnasium envs for bfqi-ga's failure tests (tests/gym_failures.rs, test_worker.py).

Each is cart-pole until step `at` of an episode (counted from its reset), then:
- `BfqiHang-v0` sleeps far beyond any timeout,
- `BfqiCrash-v0` kills its own process (exit code 7),
- `BfqiNan-v0` returns a NaN observation,
- `BfqiRaise-v0` raises an exception.

Use them as `"id": "bfqi_gym_testenvs:BfqiHang-v0"` with this folder on PYTHONPATH: gymnasium
imports the module before the `:`, which registers them.
"""

import os
import time

import numpy as np
from gymnasium.envs.classic_control.cartpole import CartPoleEnv
from gymnasium.envs.registration import register


class _Faulty(CartPoleEnv):
    def __init__(self, at=5, **kwargs):
        super().__init__(**kwargs)
        self.at = at
        self.t = 0

    def reset(self, *, seed=None, options=None):
        self.t = 0
        return super().reset(seed=seed, options=options)

    def step(self, action):
        self.t += 1
        if self.t >= self.at:
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
