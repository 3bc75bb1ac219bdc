#!/usr/bin/env bash
# `make compose-run`: Scenario 1 (or COMPOSE_FILE) in lockstep as a docker compose fleet.
# Builds what is missing (base image, wheelhouse, image: docker/build-image.sh), starts a private
# dockerd when none answers (docker/dockerd-start.sh: no iptables, no ip_forward, no bridge), runs the
# fleet, writes the run directory OUT (default runs/compose-scenario1-<UTC time>/) with the same files
# as `tlfleet run` (each service's log in OUT/logs/), prints the report, and tears down everything it
# started: `compose down` (containers, network), and the dockerd if it started one.
# A secured compose file (the default of `tlfleet compose`: --secure /fleet/keys) gets its keys from
# $TLFLEET_KEYS; when that is unset, a fresh key directory is made for this run (`tlfleet keys
# SCENARIO --host router` into a private temporary directory) and deleted at the end.
# A compose file with faults (`tlfleet compose --fault …`: the coordinator has --fault-handoff) gets
# the host's fault executor (`tlfleet compose-faults`: docker network disconnect/connect, pause/
# unpause, kill, start of this project's containers) in the background for the run, its log in
# OUT/logs/compose-faults.log; it ends with this script, undoing what is still in effect.
#   usage: docker/compose-run.sh [COMPOSE_FILE] [OUT]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
FILE=${1:-docker/compose.scenario1.yaml}
NAME=$(basename "$FILE" .yaml); NAME=${NAME#compose.}
OUT=${2:-runs/compose-$NAME-$(date -u +%Y%m%d-%H%M%S)}
export TLFLEET_DOCKER_WORK=${TLFLEET_DOCKER_WORK:-/tmp/tlfleet-docker}
PROJECT=tlfleet-$NAME-$$

if docker compose version >/dev/null 2>&1; then COMPOSE=(docker compose)
elif command -v docker-compose >/dev/null; then COMPOSE=(docker-compose)
else echo "compose-run: no docker compose (apt-get install docker-compose)" >&2; exit 1; fi

STARTED=0
if ! docker version >/dev/null 2>&1; then
  eval "$(docker/dockerd-start.sh "$TLFLEET_DOCKER_WORK")"
  STARTED=1
fi
OWN_KEYS=
EXECUTOR=
OUT_ABS=
CLAIMED=0
# The containers run as the invoking user (the compose file's `user:`), so the run directory and
# the keys are theirs; root on the host runs them as the images' own user 10001 instead, and gets
# the run directory back at the end.
HOST_IDS="$(id -u):$(id -g)"
if [[ $(id -u) == 0 ]]; then export TLFLEET_UID=10001 TLFLEET_GID=10001
else export TLFLEET_UID=$(id -u) TLFLEET_GID=$(id -g); fi
cleanup() {
  set +e
  if [[ -n $EXECUTOR ]]; then   # by its pid; it reconnects / unpauses what is still cut or paused
    kill -TERM "$EXECUTOR" 2>/dev/null
    for _ in $(seq 1 100); do kill -0 "$EXECUTOR" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$EXECUTOR" 2>/dev/null
  fi
  "${COMPOSE[@]}" -p "$PROJECT" -f "$FILE" down --timeout 5 >/dev/null 2>&1
  # what stays on disk for the next run, and how to remove it (`make clean` does)
  local images
  images=$(docker image ls --format '{{.Repository}}:{{.Tag}} ({{.Size}})' 2>/dev/null \
           | grep -E '^(tlfleet|local/tlfleet)' | paste -sd' ' -)
  echo "compose-run: kept for the next run: images ${images:-none}; docker/wheels" \
       "($(du -sh docker/wheels 2>/dev/null | cut -f1)); $TLFLEET_DOCKER_WORK" \
       "($(du -sh "$TLFLEET_DOCKER_WORK" 2>/dev/null | cut -f1)). \`make clean\` removes them." >&2
  if [[ $STARTED == 1 ]]; then docker/dockerd-stop.sh "$TLFLEET_DOCKER_WORK"; fi
  if [[ -n $OWN_KEYS ]]; then rm -rf "$OWN_KEYS"; fi
  if [[ $CLAIMED == 1 ]]; then rm -f "$OUT_ABS/run.lock"; fi
  if [[ -n $OUT_ABS && $(id -u) == 0 ]]; then chown -R "$HOST_IDS" "$OUT_ABS"; fi
}
trap cleanup EXIT

if grep -q '"--secure", "/fleet/keys"' "$FILE" && { [[ -z ${TLFLEET_KEYS:-} ]] || [[ $(id -u) == 0 ]]; }; then
  # the scenario the file mounts, relative to the file's directory
  SCEN=$(grep -o '"[^"]*:/fleet/scenario.toml:ro"' "$FILE" | head -1 | sed 's/^"//; s#:/fleet/scenario.toml:ro"$##')
  OWN_KEYS=$(mktemp -d "${TMPDIR:-/tmp}/tlfleet-compose-keys-XXXXXX")   # mode 0700
  if [[ -n ${TLFLEET_KEYS:-} ]]; then   # root's keys, copied for the containers' user
    cp -a "$TLFLEET_KEYS"/. "$OWN_KEYS"/
  else
    "${PYTHON:-python3}" -m tlfleet.cli keys "$(dirname "$FILE")/$SCEN" --out "$OWN_KEYS" --force \
      --host router >/dev/null
  fi
  chown -R "$TLFLEET_UID:$TLFLEET_GID" "$OWN_KEYS" 2>/dev/null || true
  export TLFLEET_KEYS=$OWN_KEYS
fi

docker/build-image.sh
# the run directory: new or empty (a run is never written over another), claimed for this run
# with run.lock, which the coordinator is told of (it would otherwise refuse the logs/ below)
if [[ -e $OUT && ! -d $OUT ]]; then
  echo "compose-run: $OUT exists and is not a directory: give OUT a directory for the run" >&2; exit 1
fi
if [[ -d $OUT && -n $(ls -A "$OUT") ]]; then
  echo "compose-run: $OUT holds files already: a run directory is never overwritten; give another OUT or remove it" >&2
  exit 1
fi
# logs/faults too: the fault executor runs as this user, the coordinator as the containers' one,
# and both write there (the chown below hands it to the containers)
mkdir -p "$OUT/logs/faults"
OUT_ABS=$(cd "$OUT" && pwd)
exec 9>"$OUT_ABS/run.lock"
flock -n 9 || { echo "compose-run: another run is writing into $OUT_ABS" >&2; exit 1; }
echo $$ >&9
CLAIMED=1
export TLFLEET_RUN_DIR_CLAIMED=/out   # the coordinator's view of $OUT_ABS
chown -R "$TLFLEET_UID:$TLFLEET_GID" "$OUT_ABS" 2>/dev/null || true
export TLFLEET_OUT=$OUT_ABS   # the coordinator's /out: the run directory
if grep -q '"--fault-handoff", "/out/logs/faults"' "$FILE"; then
  "${PYTHON:-python3}" -m tlfleet.cli compose-faults --dir "$OUT_ABS/logs/faults" --project "$PROJECT" \
    --parent $$ --max-wall 7200 >"$OUT_ABS/logs/compose-faults.log" 2>&1 &
  EXECUTOR=$!
fi
"${COMPOSE[@]}" -p "$PROJECT" -f "$FILE" up -d --no-build >/dev/null 2>"$OUT_ABS/logs/compose-up.log" || {
  cat "$OUT_ABS/logs/compose-up.log" >&2; exit 1; }
COORD=$("${COMPOSE[@]}" -p "$PROJECT" -f "$FILE" ps -q coordinator)
CODE=$(docker wait "$COORD")
for service in $("${COMPOSE[@]}" -p "$PROJECT" -f "$FILE" config --services); do
  log=$service; [[ $service =~ ^robot([0-9]+)$ ]] && log=agent-${BASH_REMATCH[1]}   # as tlfleet run names them
  "${COMPOSE[@]}" -p "$PROJECT" -f "$FILE" logs --no-color "$service" >"$OUT_ABS/logs/$log.log" 2>&1 || true
done
[[ -s $OUT_ABS/logs/compose-up.log ]] || rm -f "$OUT_ABS/logs/compose-up.log"
# the coordinator's stdout: the report table and the files
sed -n 's/^coordinator[^|]*| \{0,1\}//p' "$OUT_ABS/logs/coordinator.log" | grep -v '^tlfleet supervise: waiting' \
  | sed "s#/out#$OUT_ABS#g" || true
echo "compose-run: coordinator exit code $CODE; run directory: $OUT_ABS"
exit "$CODE"
