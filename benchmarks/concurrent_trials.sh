#!/bin/bash
# Several from-scratch `rodlab train` runs at once on one machine with a GPU: SAC updates on the GPU
# (--device cuda), each run's simulator on NTHR CPU cores; everything ends within LIMIT_S seconds (each run
# stops at its time limit with a checkpoint and policy), then `rodlab bench train` on the GPU and on the CPU if
# time is left, and one .tgz per task of the run directories (no checkpoints) into $OUT.
# usage: bash benchmarks/concurrent_trials.sh LIMIT_S   (env: PY, DEVICE, TRIALS="task:seed ...", STEPS, NTHR, OUT)
# Figures: BENCHMARKS.md §6 (docs/bench/train_settings/h100/).
set -u
START=$(date +%s)
LIMIT=${1:-560}
PY=${PY:-python3}
DEVICE=${DEVICE:-cuda}
TRIALS=${TRIALS:-"follow_target:2 follow_target:3 follow_target:4 ik4d:2 ik4d:3 ik4d:4 tight_obstacles_2d:0 tight_obstacles_2d:1"}
STEPS=${STEPS:-5000000}
NTHR=${NTHR:-2}
OUT=${OUT:-/tmp/gpu_out}
mkdir -p "$OUT" gpu_runs
if [ -d .whl ] && ! $PY -c "import stable_baselines3, gymnasium" 2>/dev/null; then
  $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 3
  export PYTHONPATH=/tmp/site:$PWD
else
  export PYTHONPATH=$PWD
fi
export PYTHONUNBUFFERED=1
{ date -u; nvidia-smi -L 2>&1; nproc; lscpu | grep "Model name"; free -g | head -2
  $PY -c "import torch,numba,numpy,stable_baselines3 as s;print('torch',torch.__version__,'numba',numba.__version__,'numpy',numpy.__version__,'sb3',s.__version__,'cuda',torch.cuda.is_available())"; } > "$OUT/machine.txt" 2>&1
cat "$OUT/machine.txt"
BENCH_S=${BENCH_S:-45}
now=$(date +%s)
TL=$($PY -c "print(round(($START + $LIMIT - $BENCH_S - 25 - $now) / 60, 2))")
echo "training time limit per trial: $TL min"
pids=""
for t in $TRIALS; do
  task=${t%%:*}; seed=${t##*:}; d=gpu_runs/${task}__s$seed
  resume=""; [ -f "$d/config.json" ] && resume="--resume"
  NUMBA_NUM_THREADS=$NTHR OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 \
    $PY -m rodlab_cli train $task --envs 500 --steps $STEPS --seed $seed --run-dir $d $resume --device $DEVICE \
    --time-limit $TL --eval-minutes 0 --eval-every-steps 200000 --no-replay-checkpoint --threads 1 \
    --checkpoint-minutes 2 --log-interval 30 >> $d.out 2>&1 &
  pids="$pids $!"
done
# watchdog: a trial still running 15 s past its limit gets SIGTERM (it writes its checkpoint and policy)
( sleep $($PY -c "print(int($TL*60 + 15))"); for p in $pids; do kill -TERM $p 2>/dev/null; done ) &
wd=$!
wait $pids
kill $wd 2>/dev/null
for t in $TRIALS; do task=${t%%:*}; seed=${t##*:}; echo "== $task s$seed"; tail -2 gpu_runs/${task}__s$seed.out; done
left=$(( START + LIMIT - 25 - $(date +%s) ))
if [ $left -gt 20 ]; then
  for dev in $DEVICE cpu; do
    NUMBA_NUM_THREADS=4 timeout $(( left / 2 )) $PY -m rodlab_cli bench train --task follow_target --envs 500 --iters 20 \
      --threads 4 --device $dev --json >> "$OUT/bench_train.jsonl" 2>> "$OUT/bench_train.err"
  done
fi
cat "$OUT/bench_train.jsonl" 2>/dev/null
for task in $(for t in $TRIALS; do echo ${t%%:*}; done | sort -u); do
  tar czf "$OUT/$task.tgz" --exclude=checkpoint --exclude=tb --exclude='*.tfevents*' gpu_runs/${task}__s* 2>&1
done
ls -la "$OUT"
