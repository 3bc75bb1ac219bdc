#!/usr/bin/env bash
# Stop the dockerd that dockerd-start.sh started in WORK (by the pid in its --pidfile; never by
# name) and undo what it leaves: the nsfs mount under the exec root. Images stay in WORK/root for
# the next start unless --purge is given (then WORK/root, the cache of images, is removed too).
#   usage: docker/dockerd-stop.sh [WORK] [--purge]
set -euo pipefail
WORK=${TLFLEET_DOCKER_WORK:-/tmp/tlfleet-docker}
PURGE=0
for arg in "$@"; do
  case $arg in --purge) PURGE=1 ;; *) WORK=$arg ;; esac
done
if [[ ! -f $WORK/started-by-tlfleet || ! -f $WORK/dockerd.pid ]]; then
  echo "dockerd-stop: no dockerd started by tlfleet in $WORK" >&2
  exit 0
fi
PID=$(cat "$WORK/dockerd.pid")
if kill -0 "$PID" 2>/dev/null; then
  kill -TERM "$PID"
  for _ in $(seq 1 150); do kill -0 "$PID" 2>/dev/null || break; sleep 0.1; done
  if kill -0 "$PID" 2>/dev/null; then kill -KILL "$PID"; fi
fi
if mountpoint -q "$WORK/exec/netns/default" 2>/dev/null; then umount "$WORK/exec/netns/default"; fi
rm -f "$WORK/started-by-tlfleet" "$WORK/dockerd.pid" "$WORK/docker.sock"
if [[ $PURGE == 1 ]]; then
  for m in $(awk -v r="$WORK/" 'index($2, r) == 1 {print $2}' /proc/mounts | sort -r); do umount "$m" || true; done
  rm -rf "$WORK/root" "$WORK/exec"
fi
echo "dockerd-stop: stopped dockerd $PID" >&2
