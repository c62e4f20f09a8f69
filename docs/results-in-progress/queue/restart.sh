#!/bin/bash
# Start every background queue (each resumes where it stopped) at low priority. Finished and
# retired: arms3, calib3, judge (all 46 maps judged), judge2 (replaced by judge3).
cd /work/runs-logs
for s in acting release arms4 calib5 judge3; do (setsid nohup bash $s.sh >> $s.out 2>&1 &); done
sleep 5
for p in $(pgrep -f "arms4.sh|calib5.sh"); do echo 10 > /proc/$p/autogroup; done
for p in $(pgrep -f "release.sh|acting.sh|judge3.sh"); do echo 19 > /proc/$p/autogroup; done
pgrep -af "bash .*\.sh" | grep -v restart
