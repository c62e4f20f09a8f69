#!/bin/bash
# Issue 65: every table of release 0.5.0, from the clean worktree of tag v0.5.0, resumable, in
# the order of docs/results/release-0.5.0/PLAN.md. Restart each session (same command).
cd /work/release-0.5.0 || exit 1
R=/work/runs/release-0.5.0
mkdir -p $R
N="nice -n 19"
echo "=== release 0.5.0 queue $(date) at $(git describe --tags) $(git status --porcelain --untracked-files=no | wc -l) changed files"
for name in doorway hallway intersection; do
  out=$R/shipped/$name
  [ -f $out/DONE ] && continue
  resume=""; [ -f $out/checkpoints/latest.msgpack ] && resume="--resume"
  echo "=== shipped $name $(date)"
  $N python -m train --config train/configs/$name.yaml --set num_seeds=5 --set logging.progress=false --out $out $resume && touch $out/DONE
done
if [ ! -f $R/table5/ablation.json ]; then
  echo "=== table 5 $(date)"
  $N python -m train.ablation --config train/configs/ablation.yaml --seeds 10 --episodes 100 --variants-per-group 1 --out $R/table5 --resume
fi
echo "=== tables 3-4 sgjax $(date)"
$N python -m train.reproduce --baselines cadrl cadrl_lstm any_order enforced_order only_local orca dwa social_force --out $R/tables34-sgjax --resume
if [ ! -f $R/table6/DONE ]; then
  echo "=== table 6 $(date)"
  $N python -m train.sweep --config train/configs/intersection.yaml --space train/configs/sweeps/paper_table6.yaml --out $R/table6 --no-progress && touch $R/table6/DONE
fi
echo "=== tables 3-4 socialgym $(date)"
$N python -m train.reproduce --profile socialgym --baselines cadrl cadrl_lstm any_order enforced_order only_local --out $R/tables34-socialgym --resume
echo "=== release 0.5.0 queue done $(date)"
