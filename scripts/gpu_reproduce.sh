#!/bin/bash
# Continue a `python -m train.reproduce --resume` run on an offline GPU machine (the lent device
# of ../shared/gpu.md), within a time limit, so that several sessions can finish one run:
#
#   SGJAX_GIT_COMMIT=<the checkout's `git rev-parse HEAD`> \
#     bash scripts/gpu_reproduce.sh DIR SECONDS [train.reproduce arguments]
#
# DIR (in the checkout) holds the run's results.json and, if a cell was cut off, its partial/
# checkpoints; they are copied to a scratch folder, the run resumes there for at most SECONDS,
# and results.json and partial/ are copied to $OUT every 15 s and at the end (the device sends
# back only a few files, so the tables are not: write them here with --from-results). The
# wheels of ../shared/gpu.md must be in .whl/. Put the returned files into DIR, commit, and the
# next session goes on from there.
set -u
dir=$(realpath "$1")
seconds=$2
shift 2
: "${OUT:?run on the device machine, where \$OUT is the folder that comes back}"
: "${SGJAX_GIT_COMMIT:?set it to the commit of the checkout (an installed sgjax cannot see git)}"
start=$(date +%s)
python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target /tmp/site .whl/*.whl
python3 -m pip install -q --no-index --no-deps --no-build-isolation --upgrade --target /tmp/site .
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1 SGJAX_GIT_COMMIT
work=/tmp/reproduce-run
rm -rf "$work" && mkdir -p "$work" && cp -r "$dir"/. "$work"/

send_back() {
    cp "$work/results.json" "$OUT/results.json.tmp" && mv "$OUT/results.json.tmp" "$OUT/results.json"
    rm -rf "$OUT/partial"
    if [ -d "$work/partial" ]; then cp -r "$work/partial" "$OUT/partial"; fi
}

cd /tmp || exit 1
{ nvidia-smi -L; python3 -c "import jax; print('jax', jax.__version__, jax.devices())"; } \
    | tee "$OUT/log.txt"
(while sleep 15; do send_back 2>/dev/null; done) &
copier=$!
left=$(( seconds - ($(date +%s) - start) ))
echo "installed in $(( $(date +%s) - start )) s; $left s left for the run" | tee -a "$OUT/log.txt"
timeout "$left" python3 -m train.reproduce --resume --out "$work" "$@" 2>&1 \
    | grep -v -e '^|' -e '^$' | tee -a "$OUT/log.txt"
kill "$copier"
send_back
echo "done in $(( $(date +%s) - start )) s" | tee -a "$OUT/log.txt"
