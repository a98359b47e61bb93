#!/usr/bin/env bash
# Installs lightlink's client component into a temporary prefix, builds tests/packaging/consumer
# against it with find_package(lightlink), runs it, and checks that none of the baker's
# dependencies (Embree, OpenMesh, TBB, assimp, OpenEXR) is linked: not on the consumer's link
# line, not in ldd's list, not as symbols. Usage: BUILD_DIR SOURCE_DIR CXX_COMPILER GENERATOR
set -euo pipefail
build_dir=$1 source_dir=$2 cxx=$3 generator=$4
work=$(mktemp -d "${TMPDIR:-/tmp}/lightlink_package.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
banned='embree|openmesh|libtbb|tbb::|assimp|openexr|libiex|ilmthread|tinygltf'

cmake --install "$build_dir" --prefix "$work/prefix" --component lightlink_client >"$work/install.log" ||
  { cat "$work/install.log"; fail "cmake --install"; }
# Only the exported modules' headers are installed: a consumer cannot include the baker.
others=$(cd "$work/prefix/include/lightlink" &&
         find . -name '*.h' | grep -vE '^\./(core/common|core/lights|clients/client|proto)/' || true)
[ -z "$others" ] || fail "headers outside the client's modules were installed: $others"

cmake -S "$source_dir/tests/packaging/consumer" -B "$work/build" -G "$generator" \
  -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$work/prefix" \
  >"$work/configure.log" 2>&1 || { cat "$work/configure.log"; fail "configuring the consumer"; }
cmake --build "$work/build" --verbose >"$work/build.log" 2>&1 || { cat "$work/build.log"; fail "building the consumer"; }
"$work/build/consumer" || fail "the consumer exited with $?"

link_line=$(grep -E -- '-o consumer( |$)' "$work/build.log" || true)
[ -n "$link_line" ] || { cat "$work/build.log"; fail "no link line for consumer in the build log"; }
if grep -qiE "$banned" <<<"$link_line"; then fail "the link line names a baker dependency: $link_line"; fi
if ldd "$work/build/consumer" | grep -iE "$banned"; then fail "ldd lists a baker dependency"; fi
if nm -C "$work/build/consumer" | grep -qiE 'rtcNewDevice|OpenMesh::|tbb::'; then
  fail "the consumer holds Embree/OpenMesh/TBB symbols"
fi
echo "consumer links only:"
ldd "$work/build/consumer" | awk '{print "  " $1}' | sort
