#!/usr/bin/env bash
# `make clean`'s docker part: remove what the compose runs keep for the next one. The wheelhouse
# (docker/wheels), the tlfleet images in a docker daemon that answers without tlfleet having
# started it, and the private dockerd's work directory ($TLFLEET_DOCKER_WORK: its data root with
# the images and build cache, the base image's tar), after stopping that dockerd if it runs.
#   usage: docker/clean.sh
set -uo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=${TLFLEET_DOCKER_WORK:-/tmp/tlfleet-docker}
rm -rf "$ROOT/docker/wheels"
if [[ -f $WORK/started-by-tlfleet ]]; then
  "$ROOT/docker/dockerd-stop.sh" "$WORK" --purge >/dev/null 2>&1
elif docker version >/dev/null 2>&1; then   # someone else's daemon: only tlfleet's images
  for image in "${TLFLEET_IMAGE:-tlfleet:local}" "${TLFLEET_COORDINATOR_IMAGE:-tlfleet-coordinator:local}" \
               "${TLFLEET_BASE_IMAGE:-local/tlfleet-base:bookworm}"; do
    docker image rm "$image" >/dev/null 2>&1 && echo "clean: removed the image $image"
  done
fi
# the work directory is tlfleet's alone (dockerd-start.sh made it); nothing of it is mounted now
if [[ -d $WORK ]] && ! grep -q " $WORK/" /proc/mounts; then
  rm -rf "$WORK" && echo "clean: removed $WORK"
fi
exit 0
