"""bfqi-ga's Minari bridge: a Minari dataset read into the tool's table, or written from one.

bfqi-ga runs this file (built into its binary) as `python -c <source> <command> ...`; local
datasets live under MINARI_DATASETS_PATH (minari's own rule).

- `read ID OUT.csv`: `minari.load_dataset(ID)`, written as CSV in the columns `bfqi-ga dataset
  --out` writes (episode, step, state_i, action, reward, next_state_i, terminated, truncated).
  Minari stores N + 1 observations for an episode of N steps: transition t goes from
  observations[t] to observations[t + 1]. An episode's last transition is `terminated` or
  `truncated` as Minari's flags say; one with neither (the log stopped) is `truncated`. Floats are
  written with repr(), so they read back bit for bit. Prints one JSON line: episodes, steps, the
  env spec (id, kwargs, max_episode_steps) or null, and the minari, gymnasium and numpy versions.
- `write ID IN.csv META.json`: the transitions of IN.csv (those columns) as a new Minari dataset
  ID (arrow format). META: {"obs_dim", "action": {"kind": "discrete", "n"} | {"kind": "box",
  "low", "high"}, "env": {"id", "kwargs", "max_episode_steps"} | null}. With an env, its spaces
  are the dataset's and its spec is recorded (minari's recover_environment makes it again).

Errors: one line on stderr, `<field>: <message>`, and exit status 2.
"""

import csv
import json
import sys


class Refused(Exception):
    """What cannot be read or written, with the spec field it concerns."""

    def __init__(self, field, message):
        super().__init__(message)
        self.field = field


def _imports():
    try:
        import minari
        import numpy
    except ImportError as e:
        raise Refused("data.minari", f"cannot import {e.name}: pip install minari") from e
    return minari, numpy


def _spaces_of(ds, np):
    """(obs_dim, discrete): the dataset's spaces as the tool can learn from them, else refused."""
    import gymnasium as gym

    o, a = ds.observation_space, ds.action_space
    if not isinstance(o, gym.spaces.Box) or len(o.shape) != 1:
        kind = "image" if isinstance(o, gym.spaces.Box) and len(o.shape) > 1 else "non-vector"
        raise Refused("data.minari", f"{ds.id} has {kind} observations {o}: only a 1-D Box can be learnt from")
    if isinstance(a, gym.spaces.Discrete):
        return o.shape[0], True
    if isinstance(a, gym.spaces.Box) and int(np.prod(a.shape)) == 1:
        return o.shape[0], False
    raise Refused("data.minari", f"{ds.id} has actions {a}: only Discrete or a one-value Box can be learnt from")


def _env_spec(ds):
    spec = ds.spec.env_spec
    if spec is None:
        return None
    return {"id": spec.id, "kwargs": dict(spec.kwargs or {}), "max_episode_steps": spec.max_episode_steps}


# The largest file of a dataset read (its metadata is kilobytes, an episode file megabytes).
FILE_BYTES = 16 << 30


def _check_files(dataset_id):
    """Every file of a local dataset is a regular file within FILE_BYTES: a FIFO would hang
    minari's open, a device (/dev/zero) be read until memory ran out, and an episode file minari
    cannot read be skipped without a word."""
    import os
    import stat

    try:
        from minari.storage.datasets_root_dir import get_dataset_path

        root = str(get_dataset_path(dataset_id))
    except Exception:  # another minari layout: minari's own checks apply
        return
    if not os.path.isdir(root):
        return
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            p = os.path.join(folder, name)
            try:
                st = os.stat(p)  # links followed: what minari would open
            except OSError as e:
                raise Refused("data.minari", f"{dataset_id}: {p} cannot be read ({e.strerror})") from e
            if name in dirs:
                if os.path.islink(p):
                    raise Refused("data.minari", f"{dataset_id}: {p} is a link to a folder, which is not followed")
                continue
            if not stat.S_ISREG(st.st_mode):
                raise Refused("data.minari", f"{dataset_id}: {p} is not a regular file (a FIFO, a device or a socket)")
            if st.st_size > FILE_BYTES:
                raise Refused("data.minari", f"{dataset_id}: {p} is larger than {FILE_BYTES >> 30} GiB")


def read(dataset_id, out):
    minari, np = _imports()
    _check_files(dataset_id)
    try:
        ds = minari.load_dataset(dataset_id)
    except Exception as e:  # minari raises several kinds for a missing or damaged dataset
        raise Refused("data.minari", f"cannot load {dataset_id}: {e}") from e
    d, discrete = _spaces_of(ds, np)
    header = ["episode", "step"] + [f"state_{i}" for i in range(d)] + ["action", "reward"]
    header += [f"next_state_{i}" for i in range(d)] + ["terminated", "truncated"]
    steps = 0
    read_ids = []
    with open(out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for e, ep in enumerate(ds.iterate_episodes()):
            read_ids.append(ep.id)
            obs = np.asarray(ep.observations, dtype=np.float64).reshape(len(ep.observations), d)
            acts = np.asarray(ep.actions).reshape(len(ep.rewards))
            rew = np.asarray(ep.rewards, dtype=np.float64)
            n = len(rew)
            for name, v in (("observations", obs), ("actions", acts.astype(np.float64)), ("rewards", rew)):
                bad = np.argwhere(~np.isfinite(v))
                if len(bad):
                    raise Refused("data.minari", f"{dataset_id}: episode {e} has a non-finite value in {name} at {bad[0].tolist()}")
            term, trunc = bool(ep.terminations[-1]), bool(ep.truncations[-1])
            for t in range(n):
                last = t + 1 == n
                a = int(acts[t]) if discrete else float(acts[t])
                row = [e, t] + [repr(float(x)) for x in obs[t]] + [repr(a), repr(float(rew[t]))]
                row += [repr(float(x)) for x in obs[t + 1]]
                row += [int(last and term), int(last and not term)]
                w.writerow(row)
            steps += n
    if len(read_ids) != ds.total_episodes:
        missing = sorted(set(range(ds.total_episodes)) - set(read_ids))
        shown = ", ".join(str(i) for i in missing[:10]) + (", ..." if len(missing) > 10 else "")
        raise Refused(
            "data.minari",
            f"{dataset_id}: {len(read_ids)} of its {ds.total_episodes} episodes could be read (not episode {shown})",
        )
    import gymnasium

    print(json.dumps({
        "episodes": ds.total_episodes,
        "steps": steps,
        "env": _env_spec(ds),
        "minari": minari.__version__,
        "gymnasium": gymnasium.__version__,
        "numpy": np.__version__,
    }))


def write(dataset_id, source, meta_path):
    minari, np = _imports()
    import gymnasium as gym
    from minari.data_collector.episode_buffer import EpisodeBuffer

    with open(meta_path) as f:
        meta = json.load(f)
    d = meta["obs_dim"]
    env = None
    if meta["env"] is not None:
        g = meta["env"]
        env = gym.make(g["id"], max_episode_steps=g["max_episode_steps"], **g["kwargs"])
        obs_space, act_space = env.observation_space, env.action_space
    else:
        obs_space = gym.spaces.Box(-np.inf, np.inf, (d,), np.float64)
        a = meta["action"]
        if a["kind"] == "discrete":
            act_space = gym.spaces.Discrete(a["n"])
        else:
            act_space = gym.spaces.Box(a["low"], a["high"], (1,), np.float64)
    episodes = {}
    with open(source, newline="") as f:
        r = csv.reader(f)
        next(r)
        for row in r:
            episodes.setdefault(int(row[0]), []).append(row)
    buffers = []
    for e in sorted(episodes):
        rows = episodes[e]
        obs = [[float(x) for x in rows[0][2:2 + d]]] + [[float(x) for x in row[4 + d:4 + 2 * d]] for row in rows]
        acts = [float(row[2 + d]) for row in rows]
        if isinstance(act_space, gym.spaces.Discrete):
            acts = np.array([int(a) for a in acts], dtype=np.int64)
        else:
            acts = np.array(acts, dtype=act_space.dtype).reshape(len(rows), *act_space.shape)
        buffers.append(EpisodeBuffer(
            observations=np.array(obs, dtype=obs_space.dtype),
            actions=acts,
            rewards=np.array([float(row[3 + d]) for row in rows]),
            terminations=np.array([row[-2] == "1" for row in rows]),
            truncations=np.array([row[-1] == "1" for row in rows]),
        ))
    kwargs = {"env": env} if env is not None else {"observation_space": obs_space, "action_space": act_space}
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        minari.create_dataset_from_buffers(
            dataset_id, buffer=buffers, algorithm_name="bfqi-ga random policy", data_format="arrow",
            description="Random-policy episodes written by bfqi-ga dataset --minari.", **kwargs,
        )


def main(argv):
    try:
        if len(argv) == 3 and argv[0] == "read":
            read(argv[1], argv[2])
        elif len(argv) == 4 and argv[0] == "write":
            write(argv[1], argv[2], argv[3])
        else:
            raise Refused("usage", "read ID OUT.csv | write ID IN.csv META.json")
    except Refused as e:
        print(f"{e.field}: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # anything else minari or gymnasium raise: one line, not a traceback
        print(f"data.minari: {type(e).__name__}: {e}".splitlines()[0], file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
