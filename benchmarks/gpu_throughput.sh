#!/bin/bash
# Full-stage Monte Carlo throughput on a GPU beside the same machine's CPU, in one run (issue 41,
# item 4): `monte_carlo_throughput.py` unchanged, vmap backend, the azimuth scan at planetary
# fidelity over 0.2 s per sample (as in results/monte_carlo_throughput.md). Run from the repository
# root on the GPU machine (`bash benchmarks/gpu_throughput.sh`, or `... rattle` for developed rattle); results (markdown per configuration, logs) go to ${OUT:-/tmp/gpu_out}.
# Packages the GPU image lacks (SALib, tomli_w and theirs) travel as wheels in .whl/ when present.
set -o pipefail
OUT=${OUT:-/tmp/gpu_out}; mkdir -p "$OUT"
if ls .whl/*.whl >/dev/null 2>&1; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
  export PYTHONPATH=/tmp/site
fi
export PYTHONPATH=$PWD/src${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1 XLA_PYTHON_CLIENT_PREALLOCATE=false
nvidia-smi -L 2>&1 | tee "$OUT/devices.log"
cd benchmarks || exit 1
run() { local name=$1 limit=$2; shift 2; timeout "$limit" python3 monte_carlo_throughput.py --scenes planetary --backends vmap \
  --planetary-duration 0.2 --results "$OUT" --output "$name" "$@" 2>&1 | tee "$OUT/$name.log" | grep -v "^\s*$" | tail -25; }
if [ "$1" = rattle ]; then  # the design_life verification's regime: 0.6 s, zones 100 +- 50 um (developed rattle)
  run gpu_rattle_chunk4096 250 --chunks 4096 --planetary-samples 4096 --planetary-duration 0.6 --band 50e-6
  JAX_PLATFORMS=cpu run cpu_rattle_chunk16 160 --chunks 16 --planetary-samples 16 --planetary-duration 0.6 --band 50e-6
  exit
fi
run gpu_chunk1 110 --chunks 1 --planetary-samples 2
run gpu_chunk256 140 --chunks 256 --planetary-samples 256
run gpu_chunk2048 170 --chunks 2048 --planetary-samples 2048
JAX_PLATFORMS=cpu run cpu_chunk16 100 --chunks 1 16 --planetary-samples 16
