#!/usr/bin/python3
"""The committed gRPC modules of the Python package (clients/python/lightlink/_proto) are what
proto/lightlink.proto generates now (the build's copy in <build>/clients/python/lightlink_grpc).

    grpc_modules_current.py GENERATED_DIR COMMITTED_DIR
"""
import difflib
import os
import sys


def main():
    generated, committed = sys.argv[1], sys.argv[2]
    stale = []
    for name in ("lightlink_pb2.py", "lightlink_pb2_grpc.py"):
        with open(os.path.join(generated, name), encoding="utf-8") as f:
            want = f.read()
        path = os.path.join(committed, name)
        have = open(path, encoding="utf-8").read() if os.path.exists(path) else ""
        if have != want:
            stale.append(name)
            diff = difflib.unified_diff(have.splitlines(), want.splitlines(), path, "generated", lineterm="", n=1)
            print("\n".join(list(diff)[:40]))
    if stale:
        print(f"stale: {', '.join(stale)} in {committed} differ from what proto/lightlink.proto generates; "
              "refresh them with `cmake --build build --target lightlink_python_grpc_update` and commit them")
        return 1
    print("the committed Python gRPC modules match proto/lightlink.proto")
    return 0


if __name__ == "__main__":
    sys.exit(main())
