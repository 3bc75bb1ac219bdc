#!/usr/bin/env bash
# Build what is missing for a compose fleet: the base image (docker/base-image.sh), the wheelhouse
# (docker/wheelhouse.sh) and the two tlfleet images (docker/Dockerfile's targets: IMAGE, the slim
# runtime of the router, sim and agents, and IMAGE's name with -coordinator, the coordinator's),
# with no network (`docker build --network none`). Each image carries a label with a hash of the
# project's sources: an image of the same sources is not built again.
#   usage: docker/build-image.sh [IMAGE]          (default tlfleet:local)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
IMAGE=${1:-${TLFLEET_IMAGE:-tlfleet:local}}
BASE=${TLFLEET_BASE_IMAGE:-local/tlfleet-base:bookworm}
cd "$ROOT"
SOURCES=$( (find __init__.py setup.py agent bus cli coordinator sim -name '*.py' -print0 | sort -z | xargs -0 sha256sum
            sha256sum pyproject.toml docker/Dockerfile; "${PYTHON:-.venv/bin/python}" -m pip freeze \
            --exclude-editable --disable-pip-version-check) | sha256sum | cut -c1-16)
COORD=${TLFLEET_COORDINATOR_IMAGE:-${IMAGE%%:*}-coordinator:${IMAGE##*:}}
label() { docker image inspect -f '{{index .Config.Labels "tlfleet.sources"}}' "$1" 2>/dev/null || true; }
if [[ $(label "$IMAGE") == "$SOURCES" && $(label "$COORD") == "$SOURCES" ]]; then
  echo "build-image: $IMAGE and $COORD are current (sources $SOURCES)"
  exit 0
fi
docker/base-image.sh "$BASE"
docker/wheelhouse.sh "${PYTHON:-$ROOT/.venv/bin/python}"

for pair in "runtime $IMAGE" "coordinator $COORD"; do
  read -r target tag <<<"$pair"
  OLD=$(docker image inspect -f '{{.Id}}' "$tag" 2>/dev/null || true)
  DOCKER_BUILDKIT=0 docker build --quiet --network none --target "$target" --build-arg "BASE_IMAGE=$BASE" \
    --label "tlfleet.sources=$SOURCES" -t "$tag" -f docker/Dockerfile docker >/dev/null
  echo "build-image: built $tag ($target, $(docker image inspect -f '{{.Size}}' "$tag" \
    | awk '{printf "%.0f MB", $1 / 1e6}'), sources $SOURCES)"
  # the image of the previous sources lost its tag: remove it unless a container still uses it or
  # another tag names it (then docker refuses, and it stays)
  if [[ -n $OLD && $OLD != $(docker image inspect -f '{{.Id}}' "$tag") ]] && \
     [[ -z $(docker image inspect -f '{{join .RepoTags " "}}' "$OLD" 2>/dev/null) ]]; then
    docker image rm "$OLD" >/dev/null 2>&1 && echo "build-image: removed the previous image ${OLD:7:12}" || true
  fi
done
# the build stages' layers (each holds a copy of the wheelhouse) are not needed once built
docker image prune --force --filter "label!=tlfleet.sources" >/dev/null 2>&1 || true
