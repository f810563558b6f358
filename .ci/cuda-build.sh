#!/usr/bin/env bash
# CI section "GPU build": builds the learning stages and the CUDA-vs-CPU test with
# `--features cuda` against the pinned PyPI CUDA toolkit (.ci/cuda-env.sh), on a machine with
# no GPU and no CUDA installation, so the GPU build cannot rot unnoticed. Nothing here runs on
# a GPU: the CUDA-vs-CPU test only compiles (see docs/gpu.md, "Build").
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== GPU build (--features cuda, CUDA from PyPI wheels)"
need=()
python3 -m pip --version >/dev/null 2>&1 || need+=(python3-pip)
command -v c++ >/dev/null 2>&1 || need+=(g++)
if ((${#need[@]})); then
    if ! command -v apt-get >/dev/null 2>&1; then
        echo "error: need ${need[*]} for the GPU build and apt-get is not available" >&2
        exit 1
    fi
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}"
fi

# shellcheck source=.ci/cuda-env.sh
source .ci/cuda-env.sh
nvcc --version | tail -n 2

# What is built: by default the release binaries a GPU machine runs (docs/gpu.md), in
# target/cuda. CI sets PINO_CUDA_CHECK=dev: the same crates in the dev profile in the tests'
# own target/ (after the tests), so every dependency the CPU build compiled is reused and only
# the crates that change with the feature are rebuilt (BENCHMARKS.md, "CI"). That leaves
# CUDA-linked train/calibrate/evaluate/predict in target/debug: the next plain `cargo build`
# relinks the CPU ones.
if [ "${PINO_CUDA_CHECK:-release}" = dev ]; then
    export CARGO_TARGET_DIR=target
    profile=() out=debug
else
    profile=(--release) out=release
fi
# One build of the four stages and of the CUDA parity test, resolved over the whole workspace
# (`--workspace` with dev-dependencies on, as the tests section resolves it) with CUDA on:
# every dependency keeps the features the tests compiled it with, so only candle and the crates
# above it are compiled again. Selecting the packages instead (`-p train ... --features cuda`)
# resolves fewer features of shared crates (serde, syn, bytes, hashbrown, ...) and recompiled
# nearly the whole tree: 17 min 17 s against 15 min 10 s, of which 12 min are candle-kernels'
# build script (nvcc), which no flag tried here shortened (BENCHMARKS.md, "CI").
cargo build "${profile[@]}" --locked --workspace --features pino-learn/cuda \
    --bin train --bin calibrate --bin evaluate --bin predict --test cuda_parity

# The binaries must want the driver by its soname (the stub is link-time only).
for bin in train calibrate evaluate predict; do
    if ! readelf -d "$CARGO_TARGET_DIR/$out/$bin" | grep -q 'NEEDED.*\[libcuda\.so\.1\]'; then
        echo "error: $bin does not link libcuda.so.1" >&2
        exit 1
    fi
done
echo "GPU build OK: $CARGO_TARGET_DIR/$out/{train,calibrate,evaluate,predict} (not run: no GPU in CI)"
