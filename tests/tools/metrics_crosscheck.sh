#!/usr/bin/env bash
# ctest entry for the metrics cross-check: checks that OpenImageIO's tools and a python3 with numpy
# are installed (naming the Debian package to install when not), then runs metrics_crosscheck.py.
# Without scikit-image (Debian's python3-skimage, which scripts/setup.sh installs) it skips with
# exit 77: its SSIM is the reference the check compares with.
# Usage: metrics_crosscheck.sh METRICS_TOOL WORK_DIR OBSCURA SCENE
set -euo pipefail
tool=$1
work=$2
obscura=$3
scene=$4
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
for t in idiff oiiotool; do
  if ! command -v "$t" >/dev/null 2>&1; then
    echo "metrics cross-check: '$t' not found: install the Debian package openimageio-tools" \
         "(scripts/setup.sh installs it)" >&2
    exit 1
  fi
done
# Debian's interpreter first: a python3 earlier on PATH (pyenv, venv) may lack numpy.
py=""
for p in /usr/bin/python3 python3; do
  if command -v "$p" >/dev/null 2>&1 && "$p" -c 'import numpy' >/dev/null 2>&1; then
    py=$p
    break
  fi
done
if [ -z "$py" ]; then
  echo "metrics cross-check: no python3 with numpy: install the Debian package python3-numpy" \
       "(scripts/setup.sh installs it)" >&2
  exit 1
fi
if ! "$py" -c 'import skimage.metrics' >/dev/null 2>&1; then
  echo "metrics cross-check: skipped: $py cannot import skimage: install the Debian package" \
       "python3-skimage (scripts/setup.sh installs it)" >&2
  exit 77
fi
rm -rf "$work"
mkdir -p "$work"
exec "$py" "$here/metrics_crosscheck.py" "$tool" "$work" "$obscura" "$scene"
