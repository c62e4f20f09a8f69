#!/bin/bash
# Every model missing after calib.sh (resumable per scene: crowd_fit.partial.json), from clean3
# (clean3), after calib.sh (helbing, moussaid) has finished.
while ! grep -q "calibration done" /work/runs-logs/calib.out; do sleep 60; done
cd /work/clean3
for model in hsfm orca helbing moussaid; do
  out=/work/runs/calibration/loso_$model
  [ -f $out/crowd_fit.json ] && continue
  echo "=== $model (clean3) $(date)"
  PYTHONPATH=/work/clean3 nice -n 19 python -m sgjax.command crowd loso --model $model \
    --data ../shared/pedestrians/eth_ucy --steps 100 --rollout-steps 50 --rollout-rows 4 \
    --max-seconds 600 --out $out
done
echo "=== calibration 3 done $(date)"
