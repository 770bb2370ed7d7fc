#!/bin/bash
# On the lent GPU machine, from the repository root: train the five networks (seed 0) and
# GAIDE and SIMPNet (seed 1) side by side on one GPU until $TRAIN_S s after the start.
set -u
START=$(date +%s)
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=2 MKL_NUM_THREADS=2 NUMBA_CACHE_DIR=/tmp/numba
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target /tmp/site .gpu/whl/*.whl || exit 3
export PYTHONPATH=/tmp/site
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
python3 -c "import torch, numpy, numba, scipy, yaml, trimesh; print('torch', torch.__version__, 'numpy', numpy.__version__, 'numba', numba.__version__, 'cuda', torch.cuda.is_available())"
DEADLINE=$((START + ${TRAIN_S:-430}))
RUNS=${RUNS:-"gaide:0 simpnet:0 mpnet:0 gaide-v:0 gaide-h:0 gaide:1 simpnet:1"}
N=$(echo $RUNS | wc -w)
mkdir -p /tmp/w /tmp/rates
for spec in $RUNS; do
  m=${spec%:*}; s=${spec#*:}
  mkdir -p /tmp/w/s$s
  timeout $((DEADLINE - START + 60)) python3 .gpu/drive.py --model $m --seed $s --batch ${BATCH:-256} \
    --out /tmp/w/s$s/$m.pt --deadline $DEADLINE --rates /tmp/rates --procs $N --max-steps ${MAX_STEPS:-1000000} \
    > /tmp/w/log-$m-$s.txt 2>&1 &
done
while [ $(jobs -r | wc -l) -gt 0 ]; do sleep 10; echo "t=$(( $(date +%s) - START )) s: $(nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader)"; done
wait
for f in /tmp/w/log-*.txt; do echo "== $f"; grep -v "^ *$" $f | tail -n 6; done
cat /tmp/w/log-*.txt > $OUT/train-logs.txt
for d in /tmp/w/s*; do tar -cf $OUT/weights-$(basename $d).tar -C /tmp/w $(basename $d); done
ls -la $OUT
echo "done at t=$(( $(date +%s) - START )) s"
