#!/usr/bin/env bash
# CI section "GPU build": builds the learning stages and the CUDA-vs-CPU test with
# `--features cuda` against the pinned PyPI CUDA toolkit (.ci/cuda-env.sh), on a machine with
# no GPU and no CUDA installation, so the GPU build cannot rot unnoticed. Nothing here runs on
# a GPU: the CUDA-vs-CPU test only compiles (see README "GPU build").
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

cargo build --release --locked -p train -p evaluate -p predict --features cuda
cargo test --release --locked -p pino-learn --features cuda --test cuda_parity --no-run

# The binaries must want the driver by its soname (the stub is link-time only).
for bin in train evaluate predict; do
    if ! readelf -d "$CARGO_TARGET_DIR/release/$bin" | grep -q 'NEEDED.*\[libcuda\.so\.1\]'; then
        echo "error: $bin does not link libcuda.so.1" >&2
        exit 1
    fi
done
echo "GPU build OK: $CARGO_TARGET_DIR/release/{train,evaluate,predict} (not run: no GPU in CI)"
