#!/usr/bin/env python3
"""The reference for `bfqi-ga bench search --python PY`: Keras 3 on JAX trains the networks of one
FQI iteration (the first: targets are the rewards) as a researcher would with the thesis's
settings, on the rows bfqi-ga wrote.

Input: a CSV with a header `group,x0,…,x{k-1},y`; each group is one network (an action's model
under `per_action`, or the single `input` network), rows in the order bfqi-ga trains them (the last
10 % of each group validate, as Keras's validation_split takes them). Inputs and targets are
z-scored per network (population std), as bfqi-ga does.

Early stopping: Keras 3's EarlyStopping stops after `patience` epochs without improvement, while
the thesis's Keras 1.2.1 (and bfqi-ga) stop after patience + 1; so patience + 1 is passed to keep
the same rule.

Prints one JSON line: per network its rows, epochs, seconds and the median epoch time after the
first (the first includes JAX's compilation), and the total seconds.

  pip install "keras>=3" jax numpy
  python3 keras_fqi_iteration.py rows.csv --hidden 10,10 --activation sigmoid --delta-min 0.011 --patience 75
"""
import argparse
import json
import os
import time

os.environ.setdefault("KERAS_BACKEND", "jax")
import numpy as np  # noqa: E402
import keras  # noqa: E402

p = argparse.ArgumentParser()
p.add_argument("csv")
p.add_argument("--hidden", default="10,10")
p.add_argument("--activation", default="sigmoid")
p.add_argument("--delta-min", type=float, required=True)
p.add_argument("--patience", type=int, required=True)
p.add_argument("--batch", type=int, default=2000)
p.add_argument("--max-epochs", type=int, default=5000)
p.add_argument("--validation", type=float, default=0.1)
p.add_argument("--lr", type=float, default=1e-3)
p.add_argument("--rho", type=float, default=0.9)
p.add_argument("--epsilon", type=float, default=1e-8)
p.add_argument("--seed", type=int, default=1)
a = p.parse_args()

data = np.loadtxt(a.csv, delimiter=",", skiprows=1, ndmin=2)
groups = data[:, 0].astype(int)
keras.utils.set_random_seed(a.seed)


def zscore(v):
    std = v.std(0)
    return (v - v.mean(0)) / np.where(std > 0, std, 1)


class Clock(keras.callbacks.Callback):
    def on_train_begin(self, logs=None):
        self.times = []

    def on_epoch_begin(self, epoch, logs=None):
        self.t = time.perf_counter()

    def on_epoch_end(self, epoch, logs=None):
        self.times.append(time.perf_counter() - self.t)


nets = []
start = time.perf_counter()
for g in sorted(set(groups.tolist())):
    rows = data[groups == g]
    x = zscore(rows[:, 1:-1]).astype(np.float32)
    y = zscore(rows[:, -1]).astype(np.float32)
    t = time.perf_counter()
    m = keras.Sequential(
        [keras.Input((x.shape[1],))]
        + [keras.layers.Dense(int(n), activation=a.activation) for n in a.hidden.split(",")]
        + [keras.layers.Dense(1)]
    )
    m.compile(optimizer=keras.optimizers.RMSprop(learning_rate=a.lr, rho=a.rho, epsilon=a.epsilon), loss="mse")
    clock = Clock()
    stop = keras.callbacks.EarlyStopping(monitor="val_loss", min_delta=a.delta_min, patience=a.patience + 1)
    h = m.fit(x, y, batch_size=a.batch, epochs=a.max_epochs, validation_split=a.validation, shuffle=True,
              verbose=0, callbacks=[stop, clock])
    seconds = time.perf_counter() - t
    steady = clock.times[1:] or clock.times
    nets.append({"group": g, "rows": int(x.shape[0]), "epochs": len(h.history["loss"]), "seconds": seconds,
                 "first_epoch_s": clock.times[0], "epoch_ms_median": float(np.median(steady) * 1e3)})
print(json.dumps({"seconds": time.perf_counter() - start, "networks": nets, "backend": keras.backend.backend(),
                  "keras": keras.__version__}))
