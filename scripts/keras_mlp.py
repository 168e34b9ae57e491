#!/usr/bin/env python3
"""The reference for `bfqi-ga bench learners --python PY`: Keras 3 (JAX backend) training the
thesis's MLP on a dataset CSV written by `bfqi-ga dataset` (state columns and the action as inputs,
the rewards as targets, both z-scored). Prints one JSON line: the median epoch time over --epochs
epochs after a warm-up one (validation included), and the time and epochs of one early-stopped fit.

Keras 3's EarlyStopping stops after `patience` epochs without improvement where the thesis's Keras
1.2.1 stops after patience + 1, so patience + 1 is passed.

  pip install "keras>=3" jax numpy
  python3 keras_mlp.py bicycle.csv --hidden 10,10 --activation sigmoid --delta-min 0.011 --patience 75
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
p.add_argument("--epochs", type=int, default=20)
p.add_argument("--delta-min", type=float, default=0.011)
p.add_argument("--patience", type=int, default=75)
a = p.parse_args()

with open(a.csv) as f:
    names = f.readline().strip().split(",")
table = np.loadtxt(a.csv, delimiter=",", skiprows=1, ndmin=2)
inputs = [k for k, n in enumerate(names) if n.startswith("state_")] + [names.index("action")]


def zscore(v):
    std = v.std(0)
    return (v - v.mean(0)) / np.where(std > 0, std, 1)


x = zscore(table[:, inputs]).astype(np.float32)
y = zscore(table[:, names.index("reward")]).astype(np.float32)


def network():
    m = keras.Sequential([keras.Input((x.shape[1],))]
                         + [keras.layers.Dense(int(n), activation=a.activation) for n in a.hidden.split(",")]
                         + [keras.layers.Dense(1)])
    m.compile(optimizer=keras.optimizers.RMSprop(learning_rate=1e-3, rho=0.9, epsilon=1e-8), loss="mse")
    return m


class Clock(keras.callbacks.Callback):
    def on_train_begin(self, logs=None):
        self.times = []

    def on_epoch_begin(self, epoch, logs=None):
        self.t = time.perf_counter()

    def on_epoch_end(self, epoch, logs=None):
        self.times.append(time.perf_counter() - self.t)


clock = Clock()
network().fit(x, y, batch_size=2000, epochs=a.epochs + 1, validation_split=0.1, shuffle=True, verbose=0,
              callbacks=[clock])
epoch_ms = float(np.median(clock.times[1:]) * 1e3)
stop = keras.callbacks.EarlyStopping(monitor="val_loss", min_delta=a.delta_min, patience=a.patience + 1)
t = time.perf_counter()
h = network().fit(x, y, batch_size=2000, epochs=5000, validation_split=0.1, shuffle=True, verbose=0,
                  callbacks=[stop])
print(json.dumps({"rows": int(x.shape[0]), "inputs": int(x.shape[1]), "hidden": a.hidden,
                  "activation": a.activation, "epoch_ms_median": epoch_ms,
                  "early_stopped_fit_s": time.perf_counter() - t, "epochs_run": len(h.history["loss"]),
                  "backend": keras.backend.backend()}))
