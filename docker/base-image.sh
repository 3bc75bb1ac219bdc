#!/usr/bin/env bash
# Build the local base image of every tlfleet container, with no registry (fault-injection notes §3.3):
# a Debian bookworm root file system made by mmdebstrap (debootstrap if mmdebstrap is missing) from the
# host's own Debian mirror, then `docker import`. The tar is cached in $TLFLEET_DOCKER_WORK, so a second
# call (or a second image build in the same CI run) costs only the import, and nothing at all when the
# image already exists.
#   usage: docker/base-image.sh [IMAGE]          (default local/tlfleet-base:bookworm)
set -euo pipefail
IMAGE=${1:-${TLFLEET_BASE_IMAGE:-local/tlfleet-base:bookworm}}
WORK=${TLFLEET_DOCKER_WORK:-/tmp/tlfleet-docker}
PACKAGES=python3,python3-venv,ca-certificates
mkdir -p "$WORK"
if docker image inspect "$IMAGE" >/dev/null 2>&1; then
  echo "base-image: $IMAGE exists"
  exit 0
fi
TAR="$WORK/base-bookworm.tar"
if [[ ! -s $TAR ]]; then
  # The uncommented URIs of the stanza whose Suites include bookworm (a commented snapshot URI broke debootstrap).
  MIRROR=${TLFLEET_DEBIAN_MIRROR:-}
  if [[ -z $MIRROR && -f /etc/apt/sources.list.d/debian.sources ]]; then
    MIRROR=$(awk '/^[[:space:]]*#/ {next}
                  /^[[:space:]]*$/ {if (s ~ /[[:space:]]bookworm([[:space:]]|$)/ && u) print u; u=""; s=""; next}
                  /^URIs:/ {u=$2} /^Suites:/ {s=$0}
                  END {if (s ~ /[[:space:]]bookworm([[:space:]]|$)/ && u) print u}' \
             /etc/apt/sources.list.d/debian.sources | head -1)
  fi
  if [[ -z $MIRROR && -f /etc/apt/sources.list ]]; then
    MIRROR=$(awk '/^[[:space:]]*deb[[:space:]]/ && / bookworm / {print $2; exit}' /etc/apt/sources.list)
  fi
  MIRROR=${MIRROR:-http://deb.debian.org/debian}
  echo "base-image: building a bookworm root file system from $MIRROR (about 1 min)"
  if command -v mmdebstrap >/dev/null; then
    mmdebstrap --quiet --format=tar --variant=apt --include="$PACKAGES" bookworm "$TAR.part" "$MIRROR"
  elif command -v debootstrap >/dev/null; then
    ROOTFS="$WORK/rootfs"
    rm -rf "$ROOTFS"
    debootstrap --variant=minbase --include="$PACKAGES" bookworm "$ROOTFS" "$MIRROR"
    tar -C "$ROOTFS" -cf "$TAR.part" .
    rm -rf "$ROOTFS"
  else
    echo "base-image: neither mmdebstrap nor debootstrap is installed (apt-get install mmdebstrap)" >&2
    exit 1
  fi
  mv "$TAR.part" "$TAR"
fi
docker import "$TAR" "$IMAGE" >/dev/null
echo "base-image: imported $IMAGE"
