#!/usr/bin/env bash
# The README's NEON speed estimate (Speed, "Every kernel level side by side"): emits the assembly of
# the library for aarch64 and x86-64, and runs the hottest innermost loops of the MLP's training
# epoch (the dense-layer tiles and the activation polynomials) through llvm-mca for ARM and x86 cores.
# Needs: rustup target aarch64-unknown-linux-gnu, gcc-aarch64-linux-gnu, llvm (for llvm-mca).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="$PWD/target/asm"
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
cargo rustc --release --lib --target aarch64-unknown-linux-gnu -- --emit asm >/dev/null
cargo rustc --release --lib -- --emit asm >/dev/null
a64=$(ls -t "$CARGO_TARGET_DIR"/aarch64-unknown-linux-gnu/release/deps/bfqi_ga-*.s | head -1)
x86=$(ls -t "$CARGO_TARGET_DIR"/release/deps/bfqi_ga-*.s | grep -v rcgu | head -1)
echo "== NEON (aarch64): net::epoch, the neon build inlined"
python3 scripts/mca_loops.py "$a64" '^_ZN7bfqi_ga5learn3mlp3net5epoch17h' a64 6 apple-m1 neoverse-n1
echo "== AVX2 (x86-64): net::epoch::avx2"
python3 scripts/mca_loops.py "$x86" '^_ZN7bfqi_ga5learn3mlp3net5epoch4avx2' x86 6 skylake alderlake znver2
echo "== AVX-512 (x86-64): net::epoch::avx512"
python3 scripts/mca_loops.py "$x86" '^_ZN7bfqi_ga5learn3mlp3net5epoch6avx512' x86 6 icelake-server
