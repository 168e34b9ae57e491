#!/usr/bin/env python3
"""The reference for `bfqi-ga bench learners --python PY`: scikit-learn's ExtraTreesRegressor on a
dataset CSV written by `bfqi-ga dataset` (state columns and the action as inputs, the rewards as
targets: FQI's first iteration). Prints one JSON line: the median fit time over --repeat fits,
predicted rows per second, and the time of a one-row predict (what a greedy policy asks per step).

  pip install scikit-learn numpy
  python3 sklearn_et.py data.csv --trees 50 --depth 17 --min-split 8 --min-leaf 4 --jobs 2
"""
import argparse
import json
import time

import numpy as np
from sklearn.ensemble import ExtraTreesRegressor

p = argparse.ArgumentParser()
p.add_argument("csv")
p.add_argument("--trees", type=int, default=50)
p.add_argument("--depth", type=int, default=17, help="0 = unlimited")
p.add_argument("--min-split", type=int, default=8)
p.add_argument("--min-leaf", type=int, default=4)
p.add_argument("--jobs", type=int, default=2)
p.add_argument("--repeat", type=int, default=3)
a = p.parse_args()

with open(a.csv) as f:
    names = f.readline().strip().split(",")
table = np.loadtxt(a.csv, delimiter=",", skiprows=1, ndmin=2)
inputs = [k for k, n in enumerate(names) if n.startswith("state_")] + [names.index("action")]
x = table[:, inputs].astype(np.float32)
y = table[:, names.index("reward")]

fit_s, predict_s = [], []
for r in range(a.repeat):
    model = ExtraTreesRegressor(n_estimators=a.trees, max_depth=a.depth or None, min_samples_split=a.min_split,
                                min_samples_leaf=a.min_leaf, max_features=1.0, n_jobs=a.jobs, random_state=r)
    t = time.perf_counter()
    model.fit(x, y)
    fit_s.append(time.perf_counter() - t)
    t = time.perf_counter()
    model.predict(x)
    predict_s.append(time.perf_counter() - t)
t = time.perf_counter()
for i in range(200):
    model.predict(x[i:i + 1])
one_row_s = (time.perf_counter() - t) / 200
print(json.dumps({"rows": int(x.shape[0]), "features": int(x.shape[1]), "trees": a.trees, "depth": a.depth,
                  "fit_s_median": float(np.median(fit_s)),
                  "predict_rows_per_s": float(x.shape[0] / np.median(predict_s)),
                  "single_row_predict_s": one_row_s, "jobs": a.jobs}))
