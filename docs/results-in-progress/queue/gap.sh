#!/bin/bash
# Issue 68's gap judge: both crowd-gap arms (their acting copies, made by acting.sh) among the
# recorded people of the five ETH/UCY scenes and among simulated people in the same scenes,
# from a clean worktree of 64e08dc (the simulated_crowds set), resumable.
cd /work/clean5 || exit 1
A=/work/runs/acting
while [ ! -f $A/crowd_gap_published.msgpack ] || [ ! -f $A/crowd_gap_calibrated.msgpack ]; do sleep 60; done
echo "=== gap judge $(date) ($(git log --oneline -1 | cut -c1-7))"
nice -n 10 python -m train.transfer --arm published=$A/crowd_gap_published.msgpack \
  --arm calibrated=$A/crowd_gap_calibrated.msgpack --reference published \
  --sets recorded simulated_crowds --recordings ../shared/pedestrians/eth_ucy --robots 4 \
  --episodes 100 --out /work/runs/crowd-gap-judge --resume
echo "=== gap judged $(date)"
