#!/bin/bash
# Issue 68: ORCA's constants fitted on all five ETH/UCY scenes, for a preset (the 600 s fit of
# session 40 stopped at 13 of 100 steps, unconverged): the same command with an hour per phase,
# from a clean worktree of 64e08dc, after the ORCA leave-one-scene-out (calib3.sh).
while pgrep -f "calib3.sh" > /dev/null; do sleep 60; done
cd /work/clean5 || exit 1
out=/work/runs/crowd-clean/all_orca_3600
[ -f $out/crowd_fit.json ] && exit 0
echo "=== orca, all five scenes, 3600 s a phase $(date) ($(git log --oneline -1 | cut -c1-7))"
nice -n 19 python -m sgjax.command crowd fit --model orca --data ../shared/pedestrians/eth_ucy \
  --train ETH HOTEL UNIV ZARA1 ZARA2 --max-seconds 3600 --out $out
echo "=== orca all five done $(date)"
