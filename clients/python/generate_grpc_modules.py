#!/usr/bin/python3
"""Generates the lightlink package's gRPC modules from proto/lightlink.proto.

    generate_grpc_modules.py --protoc PROTOC --plugin GRPC_PYTHON_PLUGIN --proto proto/lightlink.proto --out DIR

writes DIR/lightlink_pb2.py and DIR/lightlink_pb2_grpc.py with protoc's Python generator and
gRPC's Python plugin (Debian: protobuf-compiler, protobuf-compiler-grpc), then makes the
plugin's top-level `import lightlink_pb2` a package-relative import, so the modules live
inside the `lightlink._proto` package. The build runs it (target lightlink_python_grpc) and
the test python_grpc_current compares its output with the committed copy in
clients/python/lightlink/_proto; after a proto change refresh that copy with
`cmake --build build --target lightlink_python_grpc_update`.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--protoc", required=True)
    ap.add_argument("--plugin", required=True, help="grpc_python_plugin")
    ap.add_argument("--proto", required=True, help="proto/lightlink.proto")
    ap.add_argument("--out", required=True, help="directory for lightlink_pb2.py and lightlink_pb2_grpc.py")
    args = ap.parse_args()
    proto = os.path.abspath(args.proto)
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([args.protoc, f"--proto_path={os.path.dirname(proto)}", f"--python_out={tmp}",
                        f"--grpc_python_out={tmp}", f"--plugin=protoc-gen-grpc_python={args.plugin}", proto],
                       check=True)
        grpc_path = os.path.join(tmp, "lightlink_pb2_grpc.py")
        with open(grpc_path, encoding="utf-8") as f:
            text = f.read()
        text, n = re.subn(r"^import lightlink_pb2 as ", "from . import lightlink_pb2 as ", text, flags=re.M)
        if n != 1:
            sys.exit(f"generate_grpc_modules.py: expected one 'import lightlink_pb2' in the gRPC module, found {n}")
        with open(grpc_path, "w", encoding="utf-8") as f:
            f.write(text)
        os.makedirs(args.out, exist_ok=True)
        for name in ("lightlink_pb2.py", "lightlink_pb2_grpc.py"):
            shutil.copyfile(os.path.join(tmp, name), os.path.join(args.out, name))


if __name__ == "__main__":
    main()
