#!/bin/bash
# Issue 68: ORCA's constants fitted on all five ETH/UCY scenes for the eth_ucy preset, with the
# solver's closed-form gradient and 16 windows a batch (b283724), from the clean worktree
# /work/clean8, an hour a phase at most; then ORCA's leave-one-scene-out again with the
# settings of the published one (docs/results/calibration/loso_orca, made with the loops'
# gradient), each finished scene kept. Replaces calib4 (64e08dc: killed unfinished).
while pgrep -f "crowd fit --model orca|crowd loso --model orca" > /dev/null; do sleep 60; done
cd /work/clean8 || exit 1
out=/work/runs/crowd-clean/all_orca_fast
if [ ! -f $out/crowd_fit.json ]; then
  echo "=== orca, all five scenes $(date) ($(git log --oneline -1 | cut -c1-7))"
  nice -n 10 python -m sgjax.command crowd fit --model orca --data ../shared/pedestrians/eth_ucy \
    --train ETH HOTEL UNIV ZARA1 ZARA2 --max-seconds 3600 --out $out
  echo "=== orca all five done $(date)"
fi
out=/work/runs/calibration/loso_orca_fast
if [ ! -f $out/crowd_fit.json ]; then
  echo "=== orca leave-one-scene-out $(date)"
  nice -n 10 python -m sgjax.command crowd loso --model orca --data ../shared/pedestrians/eth_ucy \
    --steps 100 --rollout-steps 50 --rollout-rows 4 --max-seconds 600 --out $out
  echo "=== orca leave-one-scene-out done $(date)"
fi
