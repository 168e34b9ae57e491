#!/usr/bin/env python3
"""Side-by-side anchor for `bfqi-ga bench fqi --python PY`: FQI or B-FQI with scikit-learn's
ExtraTreesRegressor on a dataset CSV written by `bfqi-ga dataset`, the way a researcher would write
it with scikit-learn. Prints one JSON line with the wall time and where it went.

- FQI refits a forest each iteration; B-FQI fits a forest to the Bellman residual and keeps Q on the
  training rows and on the next states as running sums (one fit per iteration, as bfqi-ga does).
- `input` encoding: one forest on [state, action]; `per_action`: one forest per action on its rows.
- The greedy evaluation is timed as `--eval-steps` per-step predicts of every action (what the policy
  costs in a simulator loop; the simulator itself is negligible next to a predict); bfqi-ga passes the
  number of steps its own evaluation ran, or 0 to leave evaluation out.
- A B-FQI step is timed as one member's predict, as the reference figures of the FQI issue were taken.
  The real policy sums K members (K predicts, or one forest of K times the trees, whose per-tree
  dispatch costs scikit-learn more still), so for B-FQI this understates the reference: the ratio
  bfqi-ga prints errs on the reference's side.

  pip install scikit-learn numpy
  python3 sklearn_fqi.py data.csv --algo bfqi --actions 0,1,2 --encoding input --gamma 0.98 \
      --trees 50 --depth 17 --min-split 8 --min-leaf 4 --iterations 20 --eval-steps 5000 --jobs 2
"""
import argparse, json, time
import numpy as np
from sklearn.ensemble import ExtraTreesRegressor

p = argparse.ArgumentParser()
p.add_argument("csv")
p.add_argument("--algo", choices=["fqi", "bfqi"], default="fqi")
p.add_argument("--actions", required=True, help="comma-separated discrete actions of the greedy policy")
p.add_argument("--encoding", choices=["input", "per_action"], default="input")
p.add_argument("--gamma", type=float, required=True)
p.add_argument("--trees", type=int, default=50)
p.add_argument("--depth", type=int, default=17)
p.add_argument("--min-split", type=int, default=8)
p.add_argument("--min-leaf", type=int, default=4)
p.add_argument("--iterations", type=int, default=20)
p.add_argument("--eval-steps", type=int, default=5000)
p.add_argument("--jobs", type=int, default=2)
a = p.parse_args()

with open(a.csv) as f:
    header = f.readline().strip().split(",")
data = np.loadtxt(a.csv, delimiter=",", skiprows=1)
col = {h: i for i, h in enumerate(header)}
x = data[:, [i for h, i in col.items() if h.startswith("state_")]]
xn = data[:, [i for h, i in col.items() if h.startswith("next_state_")]]
act, r, absorbing = data[:, col["action"]], data[:, col["reward"]], data[:, col["terminated"]]
actions = [float(v) for v in a.actions.split(",")]
n, n_act = len(r), len(actions)


def forest(k):
    return ExtraTreesRegressor(n_estimators=a.trees, max_depth=a.depth, min_samples_split=a.min_split,
                               min_samples_leaf=a.min_leaf, max_features=1.0, n_jobs=a.jobs, random_state=k)


def with_action(s, v):
    return np.column_stack([s, np.full(len(s), v)])


if a.encoding == "input":
    train_x = [with_action(x, 0.0)]
    train_x[0][:, -1] = act
    next_x = [with_action(xn, v) for v in actions]
    groups = [np.arange(n)]
else:
    groups = [np.flatnonzero(act == v) for v in actions]
    train_x = [x[g] for g in groups]
    next_x = [xn for _ in actions]

start = time.perf_counter()
fit_s = predict_s = 0.0
q_train = np.zeros(n)
q_next = np.zeros((n, n_act))
members = []  # per model slot (1 for input, one per action), the forests fitted so far
for k in range(a.iterations):
    y = r if k == 0 else r + a.gamma * (1.0 - absorbing) * q_next.max(axis=1)
    target = y if a.algo == "fqi" else y - q_train
    t = time.perf_counter()
    models = []
    for m, g in enumerate(groups):
        f = forest(k * len(groups) + m)
        f.fit(train_x[m], target[g])
        models.append(f)
    fit_s += time.perf_counter() - t
    t = time.perf_counter()
    new_next = np.empty((n, n_act))
    for j in range(n_act):
        model = models[0] if a.encoding == "input" else models[j]
        new_next[:, j] = model.predict(next_x[j])
    if a.algo == "fqi":
        q_next = new_next
    else:
        q_next += new_next
        for m, g in enumerate(groups):
            q_train[g] += models[m].predict(train_x[m])
    predict_s += time.perf_counter() - t
    members.append(models)

# The greedy policy's cost per step: the last fitted forest of each slot (see the module doc).
policy = members[-1]
t = time.perf_counter()
for i in range(a.eval_steps):
    s = x[i % n:i % n + 1]
    if a.encoding == "input":
        q = policy[0].predict(np.column_stack([np.repeat(s, n_act, axis=0), actions]))
    else:
        q = [policy[j].predict(s)[0] for j in range(n_act)]
    int(np.argmax(q))
eval_s = time.perf_counter() - t
print(json.dumps({"algo": a.algo, "rows": n, "iterations": a.iterations, "seconds": time.perf_counter() - start,
                  "fit_s": fit_s, "predict_s": predict_s, "eval_s": eval_s, "eval_steps": a.eval_steps,
                  "jobs": a.jobs}))
