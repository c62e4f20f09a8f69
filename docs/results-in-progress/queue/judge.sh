#!/bin/bash
# Issue 66: judge the transfer arms from their acting copies (committed in
# docs/results-in-progress/transfer/arms/), from the clean v0.5.0 worktree, adding own
# specialists as they arrive (--resume plays only what is new). Restart each session.
cd /work/release-0.5.0 || exit 1
A=/work/runs/acting
OUT=/work/runs/transfer-judge
while [ ! -f $A/transfer_doorway.msgpack ]; do sleep 60; done
while true; do
  own=""; count=0
  for m in hallway intersection roundabout open; do
    if [ -f $A/transfer_$m.msgpack ]; then own="$own --own-specialist $A/transfer_$m.msgpack"; count=$((count+1)); fi
  done
  echo "=== judge with $count own specialists $(date)"
  nice -n 19 python -m train.transfer --arm specialist=$A/transfer_doorway.msgpack \
    --arm dr=$A/transfer_dr.msgpack --arm plr=$A/transfer_plr.msgpack \
    --arm families=$A/transfer_dr_families.msgpack --reference specialist \
    --own-specialist specialist $own --episodes 100 --sg2maps ../shared/sg2maps \
    --out $OUT --resume || exit 1
  [ $count = 4 ] && break
  while true; do  # wait for another own specialist
    now=0; for m in hallway intersection roundabout open; do [ -f $A/transfer_$m.msgpack ] && now=$((now+1)); done
    [ $now -gt $count ] && break
    sleep 120
  done
done
echo "=== judged $(date)"
# SFL's worst case (1,000 held-out worlds per family) runs in judge2.sh, once every arm is in
