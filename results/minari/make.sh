#!/usr/bin/env bash
# The committed Minari example (issue 48), made again from nothing: a Minari dataset of random-policy
# CartPole-v1 episodes written by the tool, a search learning from it alone, and a B-FQI vs FQI
# comparison of MLPs with the search's tuned config. Run from the repository's root with a Python
# that has gymnasium and minari (pip install "gymnasium[classic-control]" minari pillow):
#
#     BFQI_PYTHON=/path/to/python bash results/minari/make.sh
#
# Every step is seeded from the tool's streams, so the same commands give the same dataset
# (spec.json records its content hash), the same search and the same comparison, bit for bit.
set -euo pipefail
cd "$(dirname "$0")/../.."
bfqi=${BFQI_GA:-"cargo run -q --release --"}
here=results/minari
export MINARI_DATASETS_PATH="$PWD/$here/datasets"
id=bfqi/cartpole-random-v0

# 1. The dataset: 500 random-policy episodes of gymnasium's CartPole-v1 (seed 1), with its env spec
#    (minari's arrow format: about 3 MB, most of it per-episode overhead).
rm -rf "$MINARI_DATASETS_PATH" "$here/search" "$here/compare"
$bfqi dataset gymnasium:CartPole-v1 --episodes 500 --seed 1 --minari "$id"

# 2. A small GA search learning from it alone (spec.json: the env the dataset recorded, the 500
#    episodes dealt without overlap to 3 search, 3 validation and 10 comparison datasets of 30).
#    The one-liner `search minari:<id>` works too; it deals to the template's 60 datasets (8 each).
$bfqi search "$here/spec.json" --out "$here/search" --quiet

# 3. B-FQI vs FQI with the search's tuned network, on the split's 10 comparison datasets.
$bfqi compare "$here/spec.json" --tuned "$here/search/best.json" --learner mlp --analysis iterations \
  --out "$here/compare" --quiet
