#!/bin/bash
# Pause (STOP) or resume (CONT) every background queue and its children, e.g. to time something.
sig=${1:-STOP}
for p in $(pgrep -f "bash (arms3|calib3|acting|judge|release|arms4|calib4|calib5|judge2|judge3)\.sh"); do
  kill -$sig -- -$(ps -o pgid= $p | tr -d ' ') 2>/dev/null
done
ps -eo pid,stat,pgid,args | grep -E "python|bash .*\.sh" | grep -v grep | cut -c1-120
