#!/bin/bash
# Issue 66, a second attempt at the generalist: does domain randomisation over the six
# families reach the specialists with a larger budget? One seed of transfer_dr.yaml at 40M
# steps (the published arm had 6M), from the clean worktree, after arms3 (the crowd-gap arms),
# then judged beside the doorway specialist on the mini-games and SocialGym 2.0's maps.
cd /work/clean4 || exit 1
while pgrep -f "arms3.sh" > /dev/null; do sleep 60; done
R=/work/runs/exp66
name=transfer_dr_long
if [ ! -f $R/$name/DONE ]; then
  resume=""; [ -f $R/$name/checkpoints/latest.msgpack ] && resume="--resume"
  echo "=== $name $(date) (clean4 $(git log --oneline -1 | cut -c1-7))"
  nice -n 19 python -m train --config train/configs/transfer_dr.yaml --set num_seeds=1 \
    --set algorithm.total_steps=40000000 --set evaluation.every=5000000 \
    --set logging.checkpoint_every=2000000 --out $R/$name $resume && touch $R/$name/DONE
fi
[ -f $R/$name/DONE ] || exit 1
cd /work/release-0.5.0 || exit 1
A=/work/runs/acting
while [ ! -f $A/$name.msgpack ]; do sleep 60; done
echo "=== judge $name $(date)"
nice -n 19 python -m train.transfer --arm specialist=$A/transfer_doorway.msgpack \
  --arm dr=$A/transfer_dr.msgpack --arm dr_long=$A/$name.msgpack --reference specialist \
  --sets minigames sg2maps generated_test --episodes 100 --sg2maps ../shared/sg2maps \
  --out /work/runs/probe/dr_long_judge --resume
echo "=== judged $name $(date)"
