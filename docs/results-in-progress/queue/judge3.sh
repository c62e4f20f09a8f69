#!/bin/bash
# Issue 66 (replaces judge2.sh): the one-way DR arm judged beside the others on the maps, from the
# clean v0.5.0 worktree (--resume: only the new arm, on the same episodes) as soon as its acting
# copy exists; and SFL's worst case over 10,000 held-out worlds per family for every arm ready,
# from the clean worktree /work/clean10 (9ac61cd: one compiled player per family, every arm and seed its argument; rollout B plays only the worst worlds, the file
# is written after every arm's family and resumed per family).
A=/work/runs/acting
OUT=/work/runs/transfer-judge
while pgrep -f "judge.sh|judge2.sh" > /dev/null; do sleep 120; done
own=""; for m in hallway intersection roundabout open; do own="$own --own-specialist $A/transfer_$m.msgpack"; done
base="--arm specialist=$A/transfer_doorway.msgpack --arm dr=$A/transfer_dr.msgpack \
  --arm plr=$A/transfer_plr.msgpack --arm families=$A/transfer_dr_families.msgpack"
rest="--reference specialist --own-specialist specialist $own --episodes 100 \
  --sg2maps ../shared/sg2maps --out $OUT --resume"
while true; do
  ready=$([ -f $A/transfer_dr_oneway.msgpack ] && echo yes)
  args="$base"
  if [ -n "$ready" ]; then
    args="$base --arm dr_oneway=$A/transfer_dr_oneway.msgpack"
    echo "=== judge dr_oneway on the maps $(date)"
    (cd /work/release-0.5.0 && nice -n 19 python -m train.transfer $args $rest) || exit 1
  fi
  echo "=== worst worlds, arms ready: $args $(date)"
  (cd /work/clean10 && nice -n 19 python -m train.transfer $args $rest --worst-worlds 10000 \
    --alpha 0.1 0.01) || exit 1
  [ -n "$ready" ] && break
  while [ ! -f $A/transfer_dr_oneway.msgpack ]; do sleep 300; done
done
echo "=== judged $(date)"
