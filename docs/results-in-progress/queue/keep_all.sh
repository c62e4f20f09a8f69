#!/bin/bash
# Copy every background run's small, resumable files into docs/results-in-progress/ (end of session).
D=/work/main/docs/results-in-progress
R=/work/runs/release-0.5.0
mkdir -p $D/release-0.5.0
# shipped configs: published in docs/results/release-0.5.0/shipped/ (2026-11-29)
[ -f $R/table5/ablation.partial.json ] && mkdir -p $D/release-0.5.0/table5 && cp $R/table5/ablation.partial.json $D/release-0.5.0/table5/
[ -f $R/table5/ablation.json ] && mkdir -p $D/release-0.5.0/table5 && cp $R/table5/ablation.{json,md} $D/release-0.5.0/table5/ 2>/dev/null
for t in tables34-sgjax tables34-socialgym; do
  [ -f $R/$t/results.json ] && mkdir -p $D/release-0.5.0/$t && cp $R/$t/results.json $D/release-0.5.0/$t/
  ls $R/$t/partial/*.evaluation.json > /dev/null 2>&1 && mkdir -p $D/release-0.5.0/$t/partial && cp $R/$t/partial/*.evaluation.json $D/release-0.5.0/$t/partial/
done
[ -d $R/table6 ] && mkdir -p $D/release-0.5.0/table6 && cp $R/table6/*.json $D/release-0.5.0/table6/ 2>/dev/null
# the transfer judge and its arms: published in docs/results/transfer/ (2026-11-30)
cd /work/main && git status --short docs/results-in-progress | head -30
