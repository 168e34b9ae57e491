"""bfqi-ga's gymnasium worker: steps gymnasium environments for the Rust tool over pipes.

bfqi-ga starts this file (built into its binary) as `python -c <source>` with stdin and stdout as
pipes, and speaks the protocol below. The worker holds no randomness of its own: every episode is
`reset(seed=...)` with a seed the tool derived from its streams, and every action is sent by the
tool. FQI, the learners and the GA stay in Rust; only `make`, `reset`, `step` and `render` run here.

Protocol (version 1). Every message, either way, is one frame:

    u32  header length H (little-endian)
    u64  payload length P (little-endian)
    H    bytes: a JSON object, the header
    P    bytes: the arrays the header lists under "arrays", concatenated in that order

An array entry is `[name, dtype, shape]`; dtype is a numpy code (`f8` float64, `u8` uint64,
`u1` uint8), little-endian, C order. The tool sends requests (`"op"`); the worker answers each
with one reply, `"ok": true` with the results, or `"ok": false` with `"kind"` and a one-line
`"error"` (after which the tool stops the worker).

- on start, unasked: `hello` {protocol, python, gymnasium, numpy}; or, when gymnasium cannot be
  imported, `ok: false, kind: "import"` and exit.
- `open` {id, kwargs, max_episode_steps, render}: makes the env; replies its spaces:
  `observation` {kind, shape, dtype[, n]}, `action` {kind: discrete, n, start | box, shape, low,
  high, dtype | other, repr}, the registered `max_episode_steps`, `render_modes`, `dt`.
- `collect` {horizon, options; seeds u8[E], actions f8[E, horizon, A]}: episode e is reset with
  seeds[e] (and options) and takes actions[e][t] until it terminates, is truncated or reaches the
  horizon. Replies steps u8[E], terminated u1[E], obs f8[sum(steps) + E, D] (each episode's
  observations o_0 … o_T, flattened to D values), reward f8[sum(steps)].
- `reset` {options; seeds u8[E]}: resets slots 0 … E−1 (one env each) for lock-step episodes;
  replies obs f8[E, D].
- `step` {slots u8[k], actions f8[k, A]}: one step of each listed slot; replies obs f8[k, D],
  reward f8[k], terminated u1[k], truncated u1[k].
- `render` {max_width; slots u8[k]}: each slot's `render()` (rgb_array), every n-th pixel so
  the width is at most max_width; replies frames u1[k, h, w, 3].
- `quit`, or end of input: the worker exits.

Every reply also carries `busy`, the seconds the worker spent on the request (excluding reading
and writing frames), so the tool can say how much of a job ran in Python.
"""

import json
import struct
import sys
import time

PROTOCOL = 1
_PREFIX = struct.Struct("<IQ")


class WorkerError(Exception):
    """A request that cannot be served; `kind` says why (make, space, env, reset, protocol)."""

    def __init__(self, kind, message):
        super().__init__(message)
        self.kind = kind


def read_exact(stream, n):
    """n bytes from stream, or None at a clean end of input (before the first byte)."""
    chunks, got = [], 0
    while got < n:
        b = stream.read(n - got)
        if not b:
            if got == 0:
                return None
            raise WorkerError("protocol", f"input ended inside a frame ({got} of {n} bytes)")
        chunks.append(b)
        got += len(b)
    return b"".join(chunks)


def read_frame(stream):
    """(header, {name: array}) of the next frame, or None at the end of input."""
    import numpy as np

    prefix = read_exact(stream, _PREFIX.size)
    if prefix is None:
        return None
    hlen, plen = _PREFIX.unpack(prefix)
    header = json.loads(read_exact(stream, hlen) or b"{}")
    payload = read_exact(stream, plen) if plen else b""
    arrays, at = {}, 0
    for name, dtype, shape in header.get("arrays", []):
        dt = np.dtype(dtype).newbyteorder("<")
        count = 1
        for s in shape:
            count *= s
        a = np.frombuffer(payload, dtype=dt, count=count, offset=at).reshape(shape)
        at += count * dt.itemsize
        arrays[name] = a
    if at != len(payload):
        raise WorkerError("protocol", f"payload has {len(payload)} bytes, the arrays {at}")
    return header, arrays


def write_frame(stream, header, arrays=()):
    """Writes one frame: header (a dict) and arrays, a sequence of (name, numpy array)."""
    parts, listed = [], []
    if arrays:
        # Only frames with arrays need numpy: the frame that reports a failed `import numpy` has none.
        import numpy as np
    for name, a in arrays:
        a = np.ascontiguousarray(a)
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        listed.append([name, a.dtype.str.lstrip("<|="), list(a.shape)])
        parts.append(a.tobytes())
    header = dict(header, arrays=listed)
    h = json.dumps(header, separators=(",", ":"), allow_nan=False).encode()
    payload = b"".join(parts)
    stream.write(_PREFIX.pack(len(h), len(payload)))
    stream.write(h)
    stream.write(payload)
    stream.flush()


def one_line(e):
    """An exception as one line: its type and message."""
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _finite(v):
    """A bound as JSON holds it: a number, or None for an unbounded end."""
    v = float(v)
    return v if abs(v) != float("inf") and v == v else None


def describe_space(space):
    """A gymnasium space as the tool reads it (unbounded ends as None)."""
    import numpy as np
    from gymnasium import spaces

    if isinstance(space, spaces.Discrete):
        return {"kind": "discrete", "n": int(space.n), "start": int(space.start)}
    if isinstance(space, spaces.Box):
        return {
            "kind": "box",
            "shape": [int(s) for s in space.shape],
            "low": [_finite(v) for v in np.asarray(space.low, dtype=np.float64).reshape(-1)],
            "high": [_finite(v) for v in np.asarray(space.high, dtype=np.float64).reshape(-1)],
            "dtype": str(space.dtype),
        }
    return {"kind": "other", "repr": repr(space)}


class Worker:
    """The envs of one `open`, and the requests on them."""

    def __init__(self):
        self.make_args = None
        self.envs = []
        self.obs_kind = None
        self.act = None

    def _make(self):
        import gymnasium as gym

        id_, kwargs, max_steps, render = self.make_args
        extra = {"max_episode_steps": max_steps} if max_steps is not None else {}
        if render:
            extra["render_mode"] = "rgb_array"
        try:
            return gym.make(id_, **kwargs, **extra)
        except Exception as e:  # noqa: BLE001 - any failure of make is the user's env
            raise WorkerError("make", f"gymnasium.make({id_!r}) failed: {one_line(e)}") from None

    def env(self, slot):
        while len(self.envs) <= slot:
            self.envs.append(self._make())
        return self.envs[slot]

    def open(self, h):
        for e in self.envs:
            e.close()
        self.envs = []
        self.make_args = (h["id"], h.get("kwargs") or {}, h.get("max_episode_steps"), bool(h.get("render")))
        env = self.env(0)
        obs, act = describe_space(env.observation_space), describe_space(env.action_space)
        self.obs_kind, self.act = obs["kind"], act
        spec = getattr(env, "spec", None)
        u = env.unwrapped
        dt = None
        for attr in ("dt", "tau"):
            v = getattr(u, attr, None)
            if isinstance(v, (int, float)) and v > 0:
                dt = float(v)
                break
        modes = list(getattr(env, "metadata", {}).get("render_modes", []))
        return {
            "observation": obs,
            "action": act,
            "max_episode_steps": getattr(spec, "max_episode_steps", None),
            "render_modes": modes,
            "dt": dt,
        }, []

    def _obs(self, o):
        import numpy as np

        if self.obs_kind == "discrete":
            return np.array([float(o)], dtype=np.float64)
        return np.asarray(o, dtype=np.float64).reshape(-1)

    def _action(self, a):
        import numpy as np

        if self.act["kind"] == "discrete":
            return int(a[0])
        return np.asarray(a, dtype=self.act["dtype"]).reshape(self.act["shape"])

    def _reset(self, env, seed, options):
        """env.reset with the spec's options; a failure with options given is blamed on them
        (kind `reset`), so the tool can name the spec field that holds them."""
        if options is None:
            return env.reset(seed=seed)
        try:
            return env.reset(seed=seed, options=options)
        except Exception as e:  # noqa: BLE001 - the env refusing the user's options
            raise WorkerError("reset", f"reset(options={json.dumps(options)}) raised {one_line(e)}") from None

    def _need_open(self):
        if self.make_args is None:
            raise WorkerError("protocol", "no env open")

    def collect(self, h, arrays):
        import numpy as np

        self._need_open()
        seeds, actions = arrays["seeds"], arrays["actions"]
        horizon, options = int(h["horizon"]), h.get("options")
        env = self.env(0)
        steps = np.zeros(len(seeds), dtype=np.uint64)
        terminated = np.zeros(len(seeds), dtype=np.uint8)
        obs, rewards = [], []
        for e, seed in enumerate(seeds):
            o, _ = self._reset(env, int(seed), options)
            obs.append(self._obs(o))
            t = 0
            while t < horizon:
                o, r, term, trunc, _ = env.step(self._action(actions[e, t]))
                obs.append(self._obs(o))
                rewards.append(float(r))
                t += 1
                if term:
                    terminated[e] = 1
                    break
                if trunc:
                    break
            steps[e] = t
        d = len(obs[0]) if obs else 0
        return {}, [
            ("steps", steps),
            ("terminated", terminated),
            ("obs", np.array(obs, dtype=np.float64).reshape(-1, d)),
            ("reward", np.array(rewards, dtype=np.float64)),
        ]

    def reset(self, h, arrays):
        import numpy as np

        self._need_open()
        options = h.get("options")
        out = [self._obs(self._reset(self.env(i), int(s), options)[0]) for i, s in enumerate(arrays["seeds"])]
        return {}, [("obs", np.array(out, dtype=np.float64))]

    def step(self, h, arrays):
        import numpy as np

        self._need_open()
        slots, actions = arrays["slots"], arrays["actions"]
        obs = []
        rew = np.zeros(len(slots), dtype=np.float64)
        term = np.zeros(len(slots), dtype=np.uint8)
        trunc = np.zeros(len(slots), dtype=np.uint8)
        for i, slot in enumerate(slots):
            if int(slot) >= len(self.envs):
                raise WorkerError("protocol", f"slot {int(slot)} was never reset")
            o, r, te, tr, _ = self.envs[int(slot)].step(self._action(actions[i]))
            obs.append(self._obs(o))
            rew[i], term[i], trunc[i] = float(r), bool(te), bool(tr)
        d = len(obs[0]) if obs else 0
        return {}, [("obs", np.array(obs, dtype=np.float64).reshape(-1, d)), ("reward", rew),
                    ("terminated", term), ("truncated", trunc)]

    def render(self, h, arrays):
        import numpy as np

        self._need_open()
        frames = []
        for slot in arrays["slots"]:
            f = self.envs[int(slot)].render()
            if f is None:
                raise WorkerError("env", "render() returned None: the env has no rgb_array rendering")
            f = np.asarray(f)
            if f.ndim != 3 or f.shape[2] < 3:
                raise WorkerError("env", f"render() returned an array of shape {f.shape}, not (h, w, 3)")
            step = max(1, -(-f.shape[1] // int(h.get("max_width", 320))))
            frames.append(np.ascontiguousarray(f[::step, ::step, :3], dtype=np.uint8))
        if len({f.shape for f in frames}) > 1:
            raise WorkerError("env", "render() frames of different sizes")
        return {}, [("frames", np.array(frames, dtype=np.uint8))]


def serve(inp, out):
    """Answers requests from inp on out until the end of input or `quit`."""
    worker = Worker()
    ops = {"open": worker.open, "collect": worker.collect, "reset": worker.reset,
           "step": worker.step, "render": worker.render}
    while True:
        try:
            frame = read_frame(inp)
        except WorkerError as e:
            write_frame(out, {"ok": False, "kind": e.kind, "error": str(e)})
            return 1
        if frame is None:
            return 0
        header, arrays = frame
        op = header.get("op")
        if op == "quit":
            return 0
        t0 = time.perf_counter()
        try:
            if op not in ops:
                raise WorkerError("protocol", f"unknown op {op!r}")
            if op == "open":
                reply, out_arrays = ops[op](header)
            else:
                reply, out_arrays = ops[op](header, arrays)
        except WorkerError as e:
            write_frame(out, {"ok": False, "kind": e.kind, "error": str(e)})
            continue
        except Exception as e:  # noqa: BLE001 - an env's own failure, reported to the tool
            write_frame(out, {"ok": False, "kind": "env", "error": f"the env raised {one_line(e)} in {op}"})
            continue
        reply = dict(reply, ok=True, busy=time.perf_counter() - t0)
        write_frame(out, reply, out_arrays)


def main():
    import os

    # The protocol keeps the pipe the tool gave as stdout; whatever an env (or a C library) prints
    # goes to stderr instead, which the tool keeps for its error messages.
    inp = sys.stdin.buffer
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    try:
        import gymnasium
        import numpy
    except Exception as e:  # noqa: BLE001 - reported to the tool, which names the Python it ran
        write_frame(out, {"ok": False, "kind": "import", "error": one_line(e)})
        return 3
    v = sys.version_info
    write_frame(out, {"ok": True, "op": "hello", "protocol": PROTOCOL, "python": f"{v.major}.{v.minor}.{v.micro}",
                      "gymnasium": gymnasium.__version__, "numpy": numpy.__version__, "minari": minari_version()})
    return serve(inp, out)


def minari_version():
    """Minari's version when it is installed, else None: read from its metadata, since importing
    it would cost every worker's start."""
    try:
        from importlib import metadata

        return metadata.version("minari")
    except Exception:  # noqa: BLE001 - not installed, or no metadata: recorded as absent
        return None


if __name__ == "__main__":
    sys.exit(main())
