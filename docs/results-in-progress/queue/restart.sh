#!/bin/bash
# Start every background queue (each resumes where it stopped) at low priority. Finished and
# retired: arms3, calib3, calib5 (ORCA LOSO published 2026-11-29), judge (all 46 maps judged), judge2 (replaced by judge3), judge3 (worst case published 2026-11-30).
cd /work/runs-logs
for s in acting release; do (setsid nohup bash $s.sh >> $s.out 2>&1 &); done
sleep 5
# (arms4 and calib5 finished: nothing runs at nice 10)
for p in $(pgrep -f "release.sh|acting.sh"); do echo 19 > /proc/$p/autogroup; done
pgrep -af "bash .*\.sh" | grep -v restart
