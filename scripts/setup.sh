# Shared set-up for scripts/run and scripts/test (sourced): installs missing Debian packages and
# npm modules, generates the bundled meshes, configures and builds. Idempotent and quiet when
# everything is already there.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"

DEB_PACKAGES=(build-essential cmake pkg-config libembree-dev libjansson-dev libopenexr-dev
              libspng-dev libassimp-dev libcmocka-dev libvulkan-dev mesa-vulkan-drivers glslc
              vulkan-validationlayers libcurl4-openssl-dev
              libmicrohttpd-dev libsqlite3-dev libssl-dev openimageio-tools python3-numpy
              python3-skimage
              sqlite3 curl wrk chromium clang libclang-rt-14-dev libteem-dev libvolpack1-dev
              libopenmpi-dev openmpi-bin postgresql-15 libpq-dev)
command -v node >/dev/null 2>&1 || DEB_PACKAGES+=(nodejs)
command -v npm >/dev/null 2>&1 || DEB_PACKAGES+=(npm)

obs_install_packages() {
  local missing=()
  for p in "${DEB_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -q
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
  fi
}

obs_install_npm() {
  # npm ci empties node_modules first: through a link that would empty the install it points at
  # (one shared by several checkouts), so a linked node_modules is left as it is.
  if [ -L node_modules ]; then
    [ -f node_modules/.package-lock.json ] || echo "setup: node_modules is a link to no npm install" >&2
  elif [ ! -d node_modules ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
    echo "setup: npm ci"
    npm ci --no-audit --no-fund --loglevel=error
  fi
  node scripts/make-models.mjs >/dev/null
  # The MRI head of libvolpack1-dev's examples, for scenes/volume_head.json (a copy, not a link:
  # the scene tree must not reach outside itself).
  local den=/usr/share/doc/libvolpack1-dev/examples/brainsmall.den
  if [ -f "$den" ] && ! cmp -s "$den" scenes/models/brainsmall.den; then
    cp "$den" scenes/models/brainsmall.den
  fi
}

# obs_build DIR [cmake args...]
obs_build() {
  local dir=$1
  shift
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
  cmake --build "$dir" -j "$(nproc)"
}

# obs_build_targets DIR TARGET...: configures DIR as obs_build does and builds only the targets
# named (and what they depend on).
obs_build_targets() {
  local dir=$1
  shift
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$dir" -j "$(nproc)" --target "$@"
}

obs_setup() {
  obs_install_packages
  obs_install_npm
}
