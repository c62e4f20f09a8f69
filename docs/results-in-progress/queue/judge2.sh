#!/bin/bash
# Issue 66: the one-way DR arm judged beside the others, from the clean v0.5.0 worktree
# into the same transfer.json (--resume plays only the new arm, on the same episodes), after
# judge.sh's maps, then SFL's worst case for every arm (1,000 held-out worlds per family;
# 10,000 is hours per arm on 2 cores).
cd /work/release-0.5.0 || exit 1
A=/work/runs/acting
OUT=/work/runs/transfer-judge
while pgrep -f "judge.sh|train.transfer .*--out $OUT" > /dev/null || [ ! -f $A/transfer_dr_oneway.msgpack ]; do sleep 120; done
own=""; for m in hallway intersection roundabout open; do own="$own --own-specialist $A/transfer_$m.msgpack"; done
args="--arm specialist=$A/transfer_doorway.msgpack --arm dr=$A/transfer_dr.msgpack \
  --arm plr=$A/transfer_plr.msgpack --arm families=$A/transfer_dr_families.msgpack \
  --arm dr_oneway=$A/transfer_dr_oneway.msgpack --reference specialist --own-specialist specialist $own \
  --episodes 100 --sg2maps ../shared/sg2maps --out $OUT --resume"
echo "=== judge dr_oneway $(date)"
nice -n 19 python -m train.transfer $args || exit 1
echo "=== worst worlds with dr_oneway $(date)"
nice -n 19 python -m train.transfer $args --worst-worlds 1000 --alpha 0.1 0.01
echo "=== judged dr_oneway $(date)"
