#!/bin/bash
# Copy a finished arm's acting copy and small files into docs/results-in-progress/transfer/arms/.
name=$1
D=/work/main/docs/results-in-progress/transfer/arms
mkdir -p $D/$name
cp /work/runs/acting/$name.msgpack $D/
cp /work/runs/exp66/$name/{config.yaml,progress.csv,provenance.json} $D/$name/
cp /work/runs/exp66/$name/eval/seed_spread.{json,md} $D/$name/ 2>/dev/null
ls $D/$name
