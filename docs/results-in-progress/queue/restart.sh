#!/bin/bash
# Start every background queue (each resumes where it stopped) at low priority.
cd /work/runs-logs
(setsid nohup bash arms3.sh 999999 >> arms3.out 2>&1 &)
for s in calib3 acting judge release arms4 calib4 judge2; do (setsid nohup bash $s.sh >> $s.out 2>&1 &); done
sleep 5
for p in $(pgrep -f "arms3.sh|calib3.sh|judge.sh|arms4.sh|calib4.sh|judge2.sh"); do echo 10 > /proc/$p/autogroup; done
for p in $(pgrep -f "release.sh|acting.sh"); do echo 19 > /proc/$p/autogroup; done
pgrep -af "bash .*\.sh" | grep -v restart
