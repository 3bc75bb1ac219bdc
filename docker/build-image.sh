#!/usr/bin/env bash
# Build what is missing for a compose fleet: the base image (docker/base-image.sh), the wheelhouse
# (docker/wheelhouse.sh) and the tlfleet image, with no network (`docker build --network none`).
# The image carries a label with a hash of the project's sources: an image of the same sources is
# not built again.
#   usage: docker/build-image.sh [IMAGE]          (default tlfleet:local)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
IMAGE=${1:-${TLFLEET_IMAGE:-tlfleet:local}}
BASE=${TLFLEET_BASE_IMAGE:-local/tlfleet-base:bookworm}
cd "$ROOT"
SOURCES=$( (find __init__.py setup.py agent bus cli coordinator sim -name '*.py' -print0 | sort -z | xargs -0 sha256sum
            sha256sum pyproject.toml docker/Dockerfile; "${PYTHON:-.venv/bin/python}" -m pip freeze \
            --exclude-editable --disable-pip-version-check) | sha256sum | cut -c1-16)
if [[ $(docker image inspect -f '{{index .Config.Labels "tlfleet.sources"}}' "$IMAGE" 2>/dev/null || true) == "$SOURCES" ]]; then
  echo "build-image: $IMAGE is current (sources $SOURCES)"
  exit 0
fi
docker/base-image.sh "$BASE"
docker/wheelhouse.sh "${PYTHON:-$ROOT/.venv/bin/python}"
OLD=$(docker image inspect -f '{{.Id}}' "$IMAGE" 2>/dev/null || true)
DOCKER_BUILDKIT=0 docker build --quiet --network none --build-arg "BASE_IMAGE=$BASE" \
  --label "tlfleet.sources=$SOURCES" -t "$IMAGE" -f docker/Dockerfile docker >/dev/null
echo "build-image: built $IMAGE (sources $SOURCES)"
# the image of the previous sources lost its tag: remove it (≈ 1.4 GB each) unless a container
# still uses it or another tag names it (then docker refuses, and it stays)
if [[ -n $OLD && $OLD != $(docker image inspect -f '{{.Id}}' "$IMAGE") ]] && \
   [[ -z $(docker image inspect -f '{{join .RepoTags " "}}' "$OLD" 2>/dev/null) ]]; then
  docker image rm "$OLD" >/dev/null 2>&1 && echo "build-image: removed the previous image ${OLD:7:12}" || true
fi
