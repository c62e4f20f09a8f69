#!/bin/bash
# Issue 66's remaining transfer arms and issue 68's crowd-gap arms, resumable, trained from the
# clean worktree /work/clean4 (provenance: a clean commit). Waits for the DR run that arms.sh
# started from /work/main (pid given) and marks it done when its provenance is written.
DRPID=$1
while kill -0 $DRPID 2>/dev/null; do sleep 30; done
R=/work/runs/exp66
[ -f $R/transfer_dr/provenance.json ] && touch $R/transfer_dr/DONE
cd /work/clean4
train_arm() {  # name config extra-sets...
  local name=$1 config=$2; shift 2
  if [ -f $R/$name/DONE ]; then echo "$name done"; return; fi
  local resume=""; [ -f $R/$name/checkpoints/latest.msgpack ] && resume="--resume"
  echo "=== $name $(date) (clean4 $(git log --oneline -1 | cut -c1-7))"
  nice -n 19 python -m train --config $config --set num_seeds=5 "$@" --out $R/$name $resume && touch $R/$name/DONE
}
train_arm transfer_dr train/configs/transfer_dr.yaml
train_arm transfer_doorway train/configs/transfer_doorway.yaml
for m in hallway intersection roundabout open; do
  train_arm transfer_$m train/configs/transfer_doorway.yaml --set "env.scenarios=[$m]"
done
echo "=== all trained $(date)"
for kind in published calibrated; do
  name=crowd_gap_$kind
  [ -f $R/$name/DONE ] && continue
  resume=""; [ -f $R/$name/checkpoints/latest.msgpack ] && resume="--resume"
  echo "=== $name $(date)"
  nice -n 19 python -m train --config train/configs/$name.yaml --out $R/$name $resume && touch $R/$name/DONE
done
echo "=== gap trained $(date)"
