#!/bin/sh
# `pip install ./clients/python` into a fresh virtual environment that sees the system's
# packages (Debian's python3-grpcio, -protobuf, -numpy: no download), then imports the package
# from outside the source tree and checks its version and its generated modules.
#   install_test.sh PYTHON SOURCE_DIR
# Exits 77 (skipped) when the interpreter has no venv/pip or lacks grpc or numpy.
set -eu
python="$1"
src="$2"
"$python" -c "import venv, grpc, numpy, google.protobuf, setuptools, wheel" 2>/dev/null || {
  echo "skipped: venv, grpc, numpy, protobuf, setuptools or wheel missing (scripts/packages.txt)"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$python" -m venv --system-site-packages "$tmp/venv" || { echo "skipped: venv cannot be created"; exit 77; }
"$tmp/venv/bin/python" -m pip --version >/dev/null 2>&1 || { echo "skipped: no pip in the venv"; exit 77; }
cp -r "$src/clients/python" "$tmp/pkg"  # a copy: the build writes nothing into the source tree
"$tmp/venv/bin/python" -m pip install --no-deps --no-build-isolation --no-index --quiet "$tmp/pkg"
cd "$tmp"
"$tmp/venv/bin/python" - <<'PY'
import os
import lightlink
from lightlink import pb
assert lightlink.__version__ == "0.1.0", lightlink.__version__
assert "site-packages" in lightlink.__file__, lightlink.__file__
assert hasattr(pb, "GetLightsRequest") and hasattr(lightlink.Client, "open")
assert os.path.exists(os.path.join(os.path.dirname(lightlink.__file__), "py.typed"))
print("installed", lightlink.__file__)
PY
