"""Tests of the gymnasium worker on its own (no Rust): `python -m unittest discover -s python`."""

import io
import os
import subprocess
import sys
import unittest

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bfqi_gym_worker as w  # noqa: E402


class Worker:
    """The worker as bfqi-ga runs it: a child process on pipes."""

    def __init__(self):
        env = dict(os.environ, PYTHONPATH=HERE)
        with open(os.path.join(HERE, "bfqi_gym_worker.py")) as f:
            src = f.read()
        self.p = subprocess.Popen([sys.executable, "-c", src], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, env=env)
        self.hello = self.read()

    def read(self):
        return w.read_frame(self.p.stdout)

    def ask(self, header, arrays=()):
        w.write_frame(self.p.stdin, header, arrays)
        return self.read()

    def close(self):
        self.p.stdin.close()
        self.p.wait(timeout=10)
        self.p.stdout.close()
        self.p.stderr.close()


class Framing(unittest.TestCase):
    def test_arrays_round_trip(self):
        buf = io.BytesIO()
        a = np.arange(6, dtype=np.float64).reshape(2, 3) / 7
        s = np.array([1, 2**64 - 1], dtype=np.uint64)
        w.write_frame(buf, {"op": "x"}, [("a", a), ("s", s), ("e", np.zeros((0, 4)))])
        buf.seek(0)
        h, arrays = w.read_frame(buf)
        self.assertEqual(h["op"], "x")
        np.testing.assert_array_equal(arrays["a"], a)
        np.testing.assert_array_equal(arrays["s"], s)
        self.assertEqual(arrays["e"].shape, (0, 4))
        self.assertIsNone(w.read_frame(buf), "a clean end of input")

    def test_truncated_frame_is_an_error(self):
        buf = io.BytesIO()
        w.write_frame(buf, {"op": "x"}, [("a", np.ones(4))])
        cut = io.BytesIO(buf.getvalue()[:-3])
        with self.assertRaises(w.WorkerError):
            w.read_frame(cut)


class Episodes(unittest.TestCase):
    def setUp(self):
        self.w = Worker()

    def tearDown(self):
        self.w.close()

    def open(self, id_, **kw):
        h, _ = self.w.ask(dict({"op": "open", "id": id_, "kwargs": {}, "max_episode_steps": None}, **kw))
        return h

    def test_hello_names_the_versions(self):
        h, _ = self.w.hello
        self.assertTrue(h["ok"])
        self.assertEqual(h["protocol"], w.PROTOCOL)
        self.assertIn("gymnasium", h)

    def test_open_describes_the_spaces(self):
        h = self.open("CartPole-v1")
        self.assertTrue(h["ok"], h)
        self.assertEqual(h["observation"]["shape"], [4])
        self.assertEqual(h["action"], {"kind": "discrete", "n": 2, "start": 0})
        self.assertEqual(h["max_episode_steps"], 500)
        self.assertEqual(h["dt"], 0.02)
        h = self.open("Pendulum-v1")
        self.assertEqual(h["action"]["kind"], "box")
        self.assertEqual((h["action"]["low"], h["action"]["high"]), ([-2.0], [2.0]))

    def test_unknown_id_is_a_make_error(self):
        h = self.open("NoSuchEnv-v7")
        self.assertFalse(h["ok"])
        self.assertEqual(h["kind"], "make")
        self.assertIn("NoSuchEnv", h["error"])

    def collect(self, seeds, actions, horizon):
        return self.w.ask({"op": "collect", "horizon": horizon, "options": None},
                          [("seeds", np.array(seeds, dtype=np.uint64)), ("actions", actions)])

    def test_collect_is_a_function_of_seeds_and_actions(self):
        self.open("CartPole-v1")
        rng = np.random.default_rng(0)
        actions = rng.integers(0, 2, size=(3, 50, 1)).astype(np.float64)
        h, a = self.collect([11, 12, 13], actions, 50)
        self.assertTrue(h["ok"], h)
        steps = a["steps"].astype(int)
        self.assertEqual(a["obs"].shape, (steps.sum() + 3, 4))
        self.assertEqual(a["reward"].shape, (steps.sum(),))
        for s, t in zip(steps, a["terminated"]):
            self.assertTrue(t == 1 or s == 50, "an episode ends by termination or at the horizon")
        _, b = self.collect([11, 12, 13], actions, 50)
        np.testing.assert_array_equal(a["obs"], b["obs"])
        _, c = self.collect([14, 12, 13], actions, 50)
        self.assertFalse(np.array_equal(a["obs"][:5], c["obs"][:5]), "another seed, another start")

    def test_lock_step_episodes_match_collect(self):
        self.open("CartPole-v1")
        actions = np.tile(np.array([0.0, 1.0]), 10).reshape(1, 20, 1)
        _, a = self.collect([5], actions, 20)
        h, r = self.w.ask({"op": "reset", "options": None}, [("seeds", np.array([5], dtype=np.uint64))])
        obs = [r["obs"][0]]
        for t in range(int(a["steps"][0])):
            _, s = self.w.ask({"op": "step"}, [("slots", np.array([0], dtype=np.uint64)), ("actions", actions[0, t:t + 1])])
            obs.append(s["obs"][0])
        np.testing.assert_array_equal(np.array(obs), a["obs"])

    def test_an_env_that_raises_is_reported(self):
        self.open("bfqi_gym_testenvs:BfqiRaise-v0", kwargs={"at": 2})
        h, _ = self.collect([1], np.zeros((1, 10, 1)), 10)
        self.assertFalse(h["ok"])
        self.assertEqual(h["kind"], "env")
        self.assertIn("lost its state", h["error"])

    def test_reset_options_reach_the_env(self):
        self.open("CartPole-v1")
        seeds = ("seeds", np.array([3], dtype=np.uint64))
        _, r = self.w.ask({"op": "reset", "options": {"low": 0.5, "high": 0.5}}, [seeds])
        np.testing.assert_array_equal(r["obs"][0], np.float32(0.5))


if __name__ == "__main__":
    unittest.main()
