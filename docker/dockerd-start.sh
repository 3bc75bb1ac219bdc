#!/usr/bin/env bash
# Start a private dockerd that leaves the host's network as it is (fault-injection notes §3.2):
# own data root and exec root under WORK, no iptables rules, no ip_forward, no default bridge.
# Prints `export DOCKER_HOST=...` for the caller to eval. If DOCKER_HOST already answers, or the
# default socket does, nothing is started (and dockerd-stop.sh will not stop someone else's daemon).
#   usage: eval "$(docker/dockerd-start.sh [WORK])"
set -euo pipefail
WORK=${1:-${TLFLEET_DOCKER_WORK:-/tmp/tlfleet-docker}}
mkdir -p "$WORK"
if docker version >/dev/null 2>&1; then
  echo "dockerd-start: a docker daemon already answers (${DOCKER_HOST:-default socket}); not starting one" >&2
  [[ -n ${DOCKER_HOST:-} ]] && echo "export DOCKER_HOST=$DOCKER_HOST"
  exit 0
fi
SOCK="$WORK/docker.sock"
if [[ -f $WORK/dockerd.pid ]] && kill -0 "$(cat "$WORK/dockerd.pid")" 2>/dev/null; then
  echo "export DOCKER_HOST=unix://$SOCK"
  exit 0
fi
command -v dockerd >/dev/null || { echo "dockerd-start: dockerd is not installed (apt-get install docker.io)" >&2; exit 1; }
setsid dockerd --iptables=false --ip-forward=false --bridge=none \
  --data-root "$WORK/root" --exec-root "$WORK/exec" --pidfile "$WORK/dockerd.pid" \
  -H "unix://$SOCK" >"$WORK/dockerd.log" 2>&1 </dev/null &
for _ in $(seq 1 300); do   # up to 30 s; it is ready after about 0.3 s
  if DOCKER_HOST=unix://$SOCK docker version >/dev/null 2>&1; then
    touch "$WORK/started-by-tlfleet"
    echo "dockerd-start: dockerd ready (pid $(cat "$WORK/dockerd.pid"), log $WORK/dockerd.log)" >&2
    echo "export DOCKER_HOST=unix://$SOCK"
    exit 0
  fi
  sleep 0.1
done
echo "dockerd-start: dockerd did not answer within 30 s; last lines of $WORK/dockerd.log:" >&2
tail -20 "$WORK/dockerd.log" >&2
exit 1
