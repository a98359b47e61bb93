# Shared by scripts/demo, scripts/test and scripts/bench: install what is missing,
# configure and build. Source it; do not run it.
set -euo pipefail

LIGHTLINK_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export LIGHTLINK_ROOT

log() { printf '\033[1m==> %s\033[0m\n' "$*" >&2; }

# Installs the packages of scripts/packages.txt that are not installed yet.
ensure_packages() {
  local wanted missing=()
  wanted=$(grep -v '^#' "$LIGHTLINK_ROOT/scripts/packages.txt" | tr -s ' \n' '\n' | sed '/^$/d')
  for pkg in $wanted; do
    if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed'; then
      missing+=("$pkg")
    fi
  done
  if [ ${#missing[@]} -eq 0 ]; then
    return 0
  fi
  log "installing ${#missing[@]} missing packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -q
  $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
}

# Node.js + npm for the tests that check outputs with three.js's loaders and the Khronos glTF
# validator (tests/node). A machine with its own Node.js (nodesource bundles npm) keeps it:
# Debian's npm package would conflict with that nodejs, so it is installed only when no node
# is present.
ensure_node() {
  if command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1; then
    return 0
  fi
  log "installing nodejs and npm"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -q
  $sudo apt-get install -y -q --no-install-recommends nodejs npm
}

# configure_and_build BUILD_DIR [TARGET...] -- [CMAKE_OPTION...]
configure_and_build() {
  local build_dir="$1"; shift
  local targets=() options=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do targets+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  options=("$@")
  log "configuring $build_dir"
  cmake -S "$LIGHTLINK_ROOT" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE="${BUILD_TYPE:-Release}" \
    ${options[@]+"${options[@]}"} >"$build_dir.configure.log" 2>&1 || {
    cat "$build_dir.configure.log"; return 1; }
  log "building ${targets[*]:-everything} (jobs: ${JOBS:-$(nproc)})"
  local target_args=()
  for t in ${targets[@]+"${targets[@]}"}; do target_args+=(--target "$t"); done
  cmake --build "$build_dir" -j "${JOBS:-$(nproc)}" ${target_args[@]+"${target_args[@]}"}
}
