#!/bin/bash
# Issue 66's third arm: domain randomisation with one-way doorways and hallways
# (train/configs/transfer_dr_oneway.yaml, 5 seeds), from a clean worktree of b597ffd, after arms3
# (the crowd-gap arms). judge2.sh then judges it beside the other arms.
cd /work/clean6 || exit 1
while pgrep -f "arms3.sh" > /dev/null; do sleep 60; done
R=/work/runs/exp66
name=transfer_dr_oneway
[ -f $R/$name/DONE ] && exit 0
resume=""; [ -f $R/$name/checkpoints/latest.msgpack ] && resume="--resume"
echo "=== $name $(date) (clean6 $(git log --oneline -1 | cut -c1-7))"
nice -n 19 python -m train --config train/configs/$name.yaml --set num_seeds=5 \
  --set logging.progress=false --out $R/$name $resume && touch $R/$name/DONE
echo "=== $name trained $(date)"
