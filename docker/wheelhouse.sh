#!/usr/bin/env bash
# Fill docker/wheels for an offline image build: the wheel of the project (built from this clone)
# and binary wheels of every runtime dependency for the image's Python (bookworm: CPython 3.11,
# manylinux x86_64), pinned to the versions of the host's environment (constraints.txt from
# `pip freeze`), so the containers run the same numpy/pymunk/zenoh as the host and a lockstep run is
# byte-identical. Wheels already present are reused; only this step needs the package index.
#   usage: docker/wheelhouse.sh [PYTHON]     (default .venv/bin/python)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PY=${1:-$ROOT/.venv/bin/python}
WH=$ROOT/docker/wheels
IMAGE_PYTHON=${TLFLEET_IMAGE_PYTHON:-3.11}   # python3 of Debian bookworm
mkdir -p "$WH"
quiet() { grep -v "^WARNING: Location .* is ignored" >&2 || true; }
"$PY" -m pip freeze --exclude-editable --disable-pip-version-check | grep -v '^tlfleet' > "$WH/constraints.txt"
rm -f "$WH"/tlfleet-*.whl
# setuptools leaves build/ (a second copy of the sources) in the clone: removed unless it was there
had_build=$([[ -e $ROOT/build ]] && echo 1 || true)
"$PY" -m pip wheel --quiet --disable-pip-version-check --no-deps -w "$WH" "$ROOT" 2> >(quiet)
[[ -n $had_build ]] || rm -rf "$ROOT/build"
# linux_x86_64: the project's own wheel, which carries the C tracking law built on this host
PLATFORMS=(--platform linux_x86_64)
for p in manylinux_2_28 manylinux_2_27 manylinux_2_17 manylinux2014 manylinux_2_12 manylinux2010 manylinux1; do
  PLATFORMS+=(--platform "${p}_x86_64")
done
"$PY" -m pip download --quiet --disable-pip-version-check --only-binary=:all: --find-links "$WH" \
  --python-version "$IMAGE_PYTHON" --implementation cp "${PLATFORMS[@]}" \
  -c "$WH/constraints.txt" -d "$WH" "$WH"/tlfleet-*.whl 2> >(quiet)
echo "wheelhouse: $(ls "$WH"/*.whl | wc -l) wheels for CPython $IMAGE_PYTHON in $WH"
