#!/bin/bash
# Acting copies (weights and statistics, ~1 MB) of every finished run, to commit.
cd /work/main
mkdir -p /work/runs/acting
while true; do
  for d in /work/runs/exp66/*/; do
    name=$(basename $d)
    if [ -f $d/DONE ] && [ ! -f /work/runs/acting/$name.msgpack ]; then
      python -m train.export $d/checkpoints/latest.msgpack --format acting --out /work/runs/acting/$name.msgpack && echo "acting copy $name $(date)"
    fi
  done
  sleep 120
done
