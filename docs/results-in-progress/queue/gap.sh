#!/bin/bash
# Issue 68's gap judge: both crowd-gap arms (their acting copies, made by acting.sh) among the
# recorded people of the five ETH/UCY scenes, from the clean v0.5.0 worktree, resumable.
cd /work/release-0.5.0 || exit 1
A=/work/runs/acting
while [ ! -f $A/crowd_gap_published.msgpack ] || [ ! -f $A/crowd_gap_calibrated.msgpack ]; do sleep 60; done
echo "=== gap judge $(date)"
nice -n 10 python -m train.transfer --arm published=$A/crowd_gap_published.msgpack \
  --arm calibrated=$A/crowd_gap_calibrated.msgpack --reference published --sets recorded \
  --recordings ../shared/pedestrians/eth_ucy --robots 4 --episodes 100 \
  --out /work/runs/crowd-gap-judge --resume
echo "=== gap judged $(date)"
